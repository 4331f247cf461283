// Landmark and transform file modules: io.read_landmarks, io.write_landmarks, io.read_transform,
// io.write_transform (with `skelflow info` inspectors for .landmarkAscii, .fcsv and .tfm).
#include "io/landmark_io.hpp"
#include "io/names.hpp"
#include "skel/module.hpp"

namespace skel::io {
namespace {

class ReadLandmarks final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::read_landmarks, "Read landmarks (Amira .landmarkAscii, Slicer .fcsv, CSV)")
        .output<LandmarkSet>("landmarks", "the landmark sets of the file (followed by those of 'path2')")
        .path("path", "", PathRole::Input, "landmark file: .landmarkAscii, .fcsv or .csv")
        .path("path2", "", PathRole::Input, "optional second file whose sets are appended (e.g. the moving .fcsv)").optional_value()
        .choice("format", {"auto", "amira", "fcsv", "csv"}, "auto", "file format (auto: by extension, for both files)")
        .details(R"(Formats (see docs/registration.md):
- Amira `.landmarkAscii` (AmiraMesh 3D ASCII 2.0): `define Markers N`, `Parameters { NumSets k,
  ContentType "LandmarkSet" }`, declarations `Markers { float[3] Coordinates } @1`,
  `Markers { float[3] Coordinates2 } @2`, ..., then one `@K` block of N lines "x y z" per set. Amira
  stores no names: points are named L1..LN.
- 3D Slicer markups fiducial `.fcsv`: one set per file; `label` gives the names; `CoordinateSystem =
  RAS` (or 0) is converted to our LPS/ITK physical coordinates by negating x and y.
- CSV with header `set,name,x,y,z`: all sets in one file, rows of later sets matched to set 0 by name.
Two corresponding Slicer files (fixed, moving) become one object of two sets with `path2`; the
points are matched by order and the names come from `path`. Malformed files are errors naming the
file and line. Memory: O(landmarks).)");
  }
  void run(RunContext& ctx) override {
    const LandmarkFormat f = parse_landmark_format(ctx.param<std::string>("format"));
    LandmarkSet lm = read_landmarks(ctx.input_path("path"), f);
    if (!ctx.param<std::string>("path2").empty()) {
      const auto p2 = ctx.input_path("path2");
      LandmarkSet second = read_landmarks(p2, f);
      if (second.point_count() != lm.point_count()) {
        throw InputError("param 'path2': '" + p2.string() + "' has " + std::to_string(second.point_count()) +
                         " points per set; 'path' has " + std::to_string(lm.point_count()));
      }
      for (auto& s : second.sets) lm.add_set(std::move(s));
    }
    ctx.output("landmarks", std::move(lm));
  }
};
SKEL_REGISTER_MODULE(ReadLandmarks);

class WriteLandmarks final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::write_landmarks, "Write landmarks (Amira .landmarkAscii, Slicer .fcsv, CSV)")
        .input<LandmarkSet>("landmarks", "landmarks to write")
        .path("path", "", PathRole::Output, "file to create (.landmarkAscii, .fcsv or .csv); renamed into place when the run succeeds")
        .extensions({".landmarkascii", ".am", ".fcsv", ".csv"}, "format")
        .choice("format", {"auto", "amira", "fcsv", "csv"}, "auto", "file format (auto: by extension)")
        .param<int64_t>("set", -1, "write only this set (-1 = all sets; .fcsv holds one set per file)").min(-1)
        .details(R"(Writes the layout Amira writes for a LandmarkSet (`# AmiraMesh 3D ASCII 2.0`,
`define Markers N`, `Parameters { NumSets k, ContentType "LandmarkSet" }`, `Markers { float[3]
Coordinates } @1`, `Markers { float[3] Coordinates2 } @2`, ..., `# Data section follows` and the `@K`
blocks), a Slicer markups fiducial file (version 4.11 header, `CoordinateSystem = LPS`, our physical
coordinates unchanged, names as labels; one set only — choose it with `set`), or CSV `set,name,x,y,z`.
Coordinates have 17 significant digits, so reading back is exact. Names with commas or quotes cannot
be written to .fcsv/CSV (error). The file is written to a temporary name and renamed.)");
  }
  void run(RunContext& ctx) override {
    auto lm = ctx.input<LandmarkSet>("landmarks");
    const int64_t s = ctx.param<int64_t>("set");
    if (s >= lm->set_count()) {
      throw InputError("param 'set': " + std::to_string(s) + " but the landmarks have " + std::to_string(lm->set_count()) + " set(s)");
    }
    const LandmarkFormat f = parse_landmark_format(ctx.param<std::string>("format"));
    write_landmarks(ctx.output_path("path"), s >= 0 ? lm->single_set(s) : *lm,
                    resolve_landmark_format(f, ctx.final_output_path("path")));
  }
};
SKEL_REGISTER_MODULE(WriteLandmarks);

class ReadTransform final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::read_transform, "Read a transform (4x4 text matrix or ITK .tfm)")
        .output<Transform>("transform", "transform mapping moving coordinates onto fixed ones")
        .path("path", "", PathRole::Input, "transform file: .tfm (ITK) or a text 4x4 matrix")
        .choice("format", {"auto", "matrix", "itk"}, "auto", "file format (auto: .tfm is ITK, anything else a matrix)")
        .details(R"(Plain matrix: 16 numbers (4 rows of 4, row-major; or 12 for the top 3 rows), '#'
comments allowed; a `kind=rigid|similarity|affine` in a comment sets the kind, otherwise it is
classified from the matrix. ITK `.tfm` (`#Insight Transform File V1.0`, one
`AffineTransform_double_3_3` / `_float_` / `MatrixOffsetTransformBase`): ITK and Slicer store the
resampling transform fixed → moving in LPS with `T(x) = A(x − c) + c + t` (`Parameters` = A row-major
and t, `FixedParameters` = c); it is inverted here so that the result maps moving → fixed like every
skelflow transform. Other ITK transform types are errors naming the type.)");
  }
  void run(RunContext& ctx) override {
    ctx.output("transform", read_transform(ctx.input_path("path"), parse_transform_format(ctx.param<std::string>("format"))));
  }
};
SKEL_REGISTER_MODULE(ReadTransform);

class WriteTransform final : public Module {
public:
  static ModuleSpec spec() {
    return ModuleSpec(names::write_transform, "Write a transform (4x4 text matrix or ITK .tfm)")
        .input<Transform>("transform", "transform to write (moving → fixed)")
        .path("path", "", PathRole::Output, "file to create (.tfm for ITK; .txt or .mat a text matrix); renamed into place when the run succeeds")
        .extensions({".tfm", ".txt", ".mat"}, "format")
        .choice("format", {"auto", "matrix", "itk"}, "auto", "file format (auto: .tfm is ITK, anything else a matrix)")
        .details(R"(Matrix: a comment `# skelflow transform kind=<kind> maps moving -> fixed` and the 4x4
homogeneous matrix (17 significant digits). ITK `.tfm`: `AffineTransform_double_3_3` holding the
INVERSE (fixed → moving, the resampling direction ITK and Slicer expect; our physical coordinates are
ITK's LPS coordinates), centre 0, so Slicer applies it to the moving image to bring it onto the fixed
one. A singular affine transform cannot be written as .tfm (error). Written to a temporary name and
renamed.)");
  }
  void run(RunContext& ctx) override {
    const TransformFormat f = parse_transform_format(ctx.param<std::string>("format"));
    write_transform(ctx.output_path("path"), *ctx.input<Transform>("transform"),
                    resolve_transform_format(f, ctx.final_output_path("path")));
  }
};
SKEL_REGISTER_MODULE(WriteTransform);

std::string describe_landmark_file(const std::filesystem::path& p) {
  const LandmarkSet lm = read_landmarks(p);
  return lm.describe() + "\n";
}

SKEL_REGISTER_INSPECTOR("Amira landmarks", {".landmarkascii"}, describe_landmark_file);
SKEL_REGISTER_INSPECTOR("Slicer markups fiducials", {".fcsv"}, describe_landmark_file);
SKEL_REGISTER_INSPECTOR("ITK transform", {".tfm"},
                        [](const std::filesystem::path& p) { return read_transform(p).describe() + "\n"; });

}  // namespace
}  // namespace skel::io
