#pragma once
// Landmark and transform files.
//
// Landmarks:
//   - Amira `.landmarkAscii` (AmiraMesh 3D ASCII 2.0): `define Markers N`, `Parameters { NumSets k,
//     ContentType "LandmarkSet" }`, one `Markers { float[3] CoordinatesK } @K` declaration per set
//     (set 1 is `Coordinates`, set 2 `Coordinates2`, ...) and one `@K` data block of N lines "x y z"
//     per set. Point names are not stored by Amira: they are read as L1..LN.
//   - 3D Slicer markups fiducial `.fcsv` (`# Markups fiducial file version = 4.11`,
//     `# CoordinateSystem = LPS`, `# columns = id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,desc,
//     associatedNodeID`): ONE set per file, labels are the point names. Our physical coordinates are
//     ITK/LPS coordinates (index·spacing + origin), so they are written as LPS unchanged; RAS files
//     (`CoordinateSystem = RAS` or `0`) are converted on reading (x and y negated).
//   - CSV: header `set,name,x,y,z`, one row per point of each set (sets numbered 0..k-1).
// Transforms (our Transform maps moving → fixed):
//   - plain text: a comment line `# skelflow transform kind=<kind> maps moving -> fixed` and 4 rows
//     of 4 numbers (the homogeneous matrix, row-major); the reader accepts any '#' comments and
//     classifies the kind from the matrix when the comment is absent.
//   - ITK `.tfm` (`#Insight Transform File V1.0`, `Transform: AffineTransform_double_3_3`,
//     `Parameters:` 9 matrix entries row-major + 3 translation, `FixedParameters:` centre). ITK and
//     Slicer store the *resampling* transform, which maps fixed → moving points in LPS; the writer
//     therefore writes the INVERSE of our transform (centre 0) and the reader inverts back, so a
//     file written here, loaded into Slicer and applied to the moving image moves it onto fixed.
// Every writer writes a temporary sibling file and renames it (write_atomically).
#include <filesystem>
#include <string>

#include "skel/landmarks.hpp"
#include "skel/transform.hpp"

namespace skel::io {

enum class LandmarkFormat { Auto, Amira, Fcsv, Csv };
enum class TransformFormat { Auto, Matrix, Itk };

// "auto" | "amira" | "fcsv" | "csv" (InputError otherwise).
LandmarkFormat parse_landmark_format(const std::string& text);
// "auto" | "matrix" | "itk" (InputError otherwise).
TransformFormat parse_transform_format(const std::string& text);
// Auto → by extension: .landmarkAscii/.am → Amira, .fcsv → Fcsv, .csv → Csv (InputError otherwise).
LandmarkFormat resolve_landmark_format(LandmarkFormat format, const std::filesystem::path& path);
// Auto → .tfm → Itk, anything else → Matrix.
TransformFormat resolve_transform_format(TransformFormat format, const std::filesystem::path& path);

// Throws InputError (with the file name and line) for unreadable or malformed files.
LandmarkSet read_landmarks(const std::filesystem::path& path, LandmarkFormat format = LandmarkFormat::Auto);
// Throws InputError if the format cannot hold the object (.fcsv with more than one set, names with
// commas or line breaks in .fcsv/.csv). Coordinates are written with 17 significant digits.
void write_landmarks(const std::filesystem::path& path, const LandmarkSet& landmarks,
                     LandmarkFormat format = LandmarkFormat::Auto);

Transform read_transform(const std::filesystem::path& path, TransformFormat format = TransformFormat::Auto);
void write_transform(const std::filesystem::path& path, const Transform& transform,
                     TransformFormat format = TransformFormat::Auto);

// Text versions (used by the file functions; handy for tests). `name` appears in error messages.
LandmarkSet parse_landmarks(const std::string& text, LandmarkFormat format, const std::string& name);
std::string format_landmarks(const LandmarkSet& landmarks, LandmarkFormat format);
Transform parse_transform(const std::string& text, TransformFormat format, const std::string& name);
std::string format_transform(const Transform& transform, TransformFormat format);

}  // namespace skel::io
