// Landmark and transform files: exact round trips in every format, the Amira layout, Slicer's
// coordinate systems, ITK's direction and centre conventions, clear errors.
#include <gtest/gtest.h>

#include <fstream>
#include <functional>

#include "io/landmark_io.hpp"
#include "registration/registration.hpp"
#include "../registration/test_util.hpp"

using namespace skel::io;

using namespace skel;
using namespace skel::registration;
using namespace skel::test;
namespace fs = std::filesystem;

namespace {

// One folder per test: ctest runs the tests as parallel processes, and a test that checks its folder
// for temporaries must not see another test's file being written.
fs::path scratch(const std::string& name) {
  const fs::path dir = fs::path(SKEL_BINARY_DIR) / "test_scratch" / "landmark_io" /
                       ::testing::UnitTest::GetInstance()->current_test_info()->name();
  fs::create_directories(dir);
  return dir / name;
}

void write_text(const fs::path& p, const std::string& text) {
  std::ofstream o(p, std::ios::binary);
  o << text;
}

std::string read_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

LandmarkSet sample_landmarks(int sets) {
  std::vector<std::vector<Vec3>> s;
  for (int k = 0; k < sets; ++k) s.push_back(random_points(5, 40 + static_cast<uint32_t>(k), 123.456));
  return LandmarkSet(std::move(s), {"tip", "fork 1", "L3", "base", "apex"});
}

void expect_no_temporaries(const fs::path& dir) {
  for (const auto& e : fs::directory_iterator(dir))
    EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << e.path();
}

}  // namespace

TEST(LandmarkFiles, AmiraLayoutIsWhatAmiraWrites) {
  const LandmarkSet lm({{{1, 2, 3}, {4.5, 5, 6}}, {{7, 8, 9.25}, {-1, 0, 1e-3}}});
  const std::string expected =
      "# AmiraMesh 3D ASCII 2.0\n\n\n"
      "define Markers 2\n\n"
      "Parameters {\n    NumSets 2,\n    ContentType \"LandmarkSet\"\n}\n\n"
      "Markers { float[3] Coordinates } @1\n"
      "Markers { float[3] Coordinates2 } @2\n\n"
      "# Data section follows\n"
      "@1\n1 2 3\n4.5 5 6\n\n"
      "@2\n7 8 9.25\n-1 0 0.001\n\n";
  EXPECT_EQ(format_landmarks(lm, LandmarkFormat::Amira), expected);
}

TEST(LandmarkFiles, RoundTripEveryFormat) {
  for (int sets : {1, 2, 3}) {
    const LandmarkSet lm = sample_landmarks(sets);
    // Amira stores no names: coordinates exact, names L1..Ln.
    const fs::path am = scratch("lm" + std::to_string(sets) + ".landmarkAscii");
    write_landmarks(am, lm);
    const LandmarkSet a = read_landmarks(am);
    EXPECT_EQ(a.sets, lm.sets);
    EXPECT_EQ(a.names, (std::vector<std::string>{"L1", "L2", "L3", "L4", "L5"}));
    // CSV keeps everything.
    const fs::path csv = scratch("lm" + std::to_string(sets) + ".csv");
    write_landmarks(csv, lm);
    EXPECT_TRUE(read_landmarks(csv) == lm);
    // fcsv: one set per file.
    for (int s = 0; s < sets; ++s) {
      const fs::path fcsv = scratch("lm" + std::to_string(sets) + "_" + std::to_string(s) + ".fcsv");
      write_landmarks(fcsv, lm.single_set(s));
      EXPECT_TRUE(read_landmarks(fcsv) == lm.single_set(s));
    }
    if (sets > 1) {
      EXPECT_THROW(write_landmarks(scratch("bad.fcsv"), lm), InputError);
    }
  }
  expect_no_temporaries(scratch("x").parent_path());
}

TEST(LandmarkFiles, ReadsAmiraVariants) {
  // Older header style with '= @1', extra per-marker data, values split over lines.
  const std::string text =
      "# AmiraMesh ASCII 1.0\n"
      "define Markers 2 Parameters {\nContentType \"LandmarkSet\",NumSets 1\n}\n"
      "Markers { float[3] Coordinates } = @1\n"
      "Markers { int Ids } = @2\n\n"
      "@1\n1 2 3 4\n5 6\n"
      "@2\n7\n8\n";
  const LandmarkSet lm = parse_landmarks(text, LandmarkFormat::Amira, "old.landmarkAscii");
  ASSERT_EQ(lm.set_count(), 1);
  EXPECT_EQ(lm.sets[0], (std::vector<Vec3>{{1, 2, 3}, {4, 5, 6}}));
  try {
    (void)parse_landmarks("# AmiraMesh 3D ASCII 2.0\ndefine Markers 2\nMarkers { float[3] Coordinates } @1\n@1\n1 2 3\n",
                          LandmarkFormat::Amira, "short.landmarkAscii");
    ADD_FAILURE() << "short block accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("short.landmarkAscii:4"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("expected 6"), std::string::npos) << e.what();
  }
  EXPECT_THROW((void)parse_landmarks("hello\n", LandmarkFormat::Amira, "x"), InputError);
}

TEST(LandmarkFiles, SlicerCoordinateSystems) {
  const std::string lps =
      "# Markups fiducial file version = 4.11\n# CoordinateSystem = LPS\n"
      "# columns = id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,desc,associatedNodeID\n"
      "vtkMRMLMarkupsFiducialNode_0,1.5,-2,3,0,0,0,1,1,1,0,F-1,,\n"
      "vtkMRMLMarkupsFiducialNode_1,4,5,6,0,0,0,1,1,1,0,F-2,,\n";
  const LandmarkSet a = parse_landmarks(lps, LandmarkFormat::Fcsv, "a.fcsv");
  EXPECT_EQ(a.names, (std::vector<std::string>{"F-1", "F-2"}));
  EXPECT_EQ(a.sets[0][0], (Vec3{1.5, -2, 3}));
  std::string ras = lps;
  ras.replace(ras.find("LPS"), 3, "RAS");
  const LandmarkSet b = parse_landmarks(ras, LandmarkFormat::Fcsv, "b.fcsv");
  EXPECT_EQ(b.sets[0][0], (Vec3{-1.5, 2, 3}));
  std::string old = lps;
  old.replace(old.find("LPS"), 3, "0");  // Slicer 4.6-4.10: 0 = RAS
  EXPECT_EQ(parse_landmarks(old, LandmarkFormat::Fcsv, "c.fcsv").sets[0][1], (Vec3{-4, -5, 6}));
  // Our writer declares LPS and keeps the coordinates.
  const std::string w = format_landmarks(a, LandmarkFormat::Fcsv);
  EXPECT_EQ(w.rfind("# Markups fiducial file version = 4.11\n# CoordinateSystem = LPS\n", 0), 0u);
  EXPECT_THROW((void)parse_landmarks("1,2,3\n", LandmarkFormat::Fcsv, "nohdr.fcsv"), InputError);
  EXPECT_THROW((void)format_landmarks(LandmarkSet({{{0, 0, 0}}}, {"a,b"}), LandmarkFormat::Fcsv), InputError);
}

// The CSV header carries the unit ("x [mm]") and reading takes it back; a header without one
// gives the default unit.
TEST(LandmarkFiles, CsvKeepsTheUnit) {
  LandmarkSet lm = sample_landmarks(2);
  lm.unit = "mm";
  const std::string text = format_landmarks(lm, LandmarkFormat::Csv);
  EXPECT_EQ(text.rfind("set,name,x [mm],y [mm],z [mm]\n", 0), 0u) << text.substr(0, 80);
  const LandmarkSet r = parse_landmarks(text, LandmarkFormat::Csv, "mm.csv");
  EXPECT_EQ(r.unit, "mm");
  EXPECT_TRUE(r == lm);
  EXPECT_EQ(parse_landmarks("set,name,x,y,z\n0,a,1,2,3\n", LandmarkFormat::Csv, "t.csv").unit, kDefaultUnit);
}

TEST(LandmarkFiles, CsvMatchesSetsByName) {
  const std::string text = "set,name,x,y,z\n1,b,7,8,9\n0,a,1,2,3\n0,b,4,5,6\n1,a,10,11,12\n";
  const LandmarkSet lm = parse_landmarks(text, LandmarkFormat::Csv, "t.csv");
  EXPECT_EQ(lm.names, (std::vector<std::string>{"a", "b"}));
  EXPECT_EQ(lm.sets[0], (std::vector<Vec3>{{1, 2, 3}, {4, 5, 6}}));
  EXPECT_EQ(lm.sets[1], (std::vector<Vec3>{{10, 11, 12}, {7, 8, 9}}));
  EXPECT_THROW((void)parse_landmarks("set,name,x,y,z\n0,a,1,2,3\n1,c,1,2,3\n", LandmarkFormat::Csv, "t.csv"), InputError);
  EXPECT_THROW((void)parse_landmarks("set,name,x,y\n", LandmarkFormat::Csv, "t.csv"), InputError);
  EXPECT_THROW((void)parse_landmarks("set,name,x,y,z\n0,a,1,zz,3\n", LandmarkFormat::Csv, "t.csv"), InputError);
  EXPECT_THROW((void)resolve_landmark_format(LandmarkFormat::Auto, "x.txt"), InputError);
}

// Non-finite coordinates are refused with the file, the line and the token (before, `inf` and
// `1e400` were read and gave infinite distances; `nan` a misleading message downstream).
TEST(LandmarkFiles, RefusesNonFiniteCoordinates) {
  for (const std::string bad : {"inf", "-inf", "nan", "1e400"}) {
    try {
      (void)parse_landmarks("set,name,x,y,z\n0,a,1," + bad + ",3\n", LandmarkFormat::Csv, "t.csv");
      ADD_FAILURE() << bad << " was accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("t.csv:2"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("not a finite number"), std::string::npos) << e.what();
    }
    EXPECT_THROW((void)parse_landmarks("# AmiraMesh 3D ASCII 2.0\ndefine Markers 1\nMarkers { float[3] Coordinates } @1\n@1\n1 " +
                                           bad + " 3\n",
                                       LandmarkFormat::Amira, "x.landmarkAscii"),
                 InputError)
        << bad;
  }
}

TEST(TransformFiles, RoundTripEveryFormat) {
  for (const Transform& t : {known_rigid(), known_similarity(), known_affine()}) {
    SCOPED_TRACE(to_string(t.kind()));
    const fs::path m = scratch("t_" + to_string(t.kind()) + ".txt");
    write_transform(m, t);
    const Transform a = read_transform(m);
    EXPECT_TRUE(a == t);  // 17 digits: bitwise exact
    EXPECT_EQ(read_text(m).rfind("# skelflow transform kind=" + to_string(t.kind()) + " maps moving -> fixed", 0), 0u);
    const fs::path itk = scratch("t_" + to_string(t.kind()) + ".tfm");
    write_transform(itk, t);
    const Transform b = read_transform(itk);
    EXPECT_LT(b.max_difference(t), 1e-12);  // inverted twice
    EXPECT_EQ(b.kind(), t.kind());          // classified from the matrix
  }
  expect_no_temporaries(scratch("x").parent_path());
}

TEST(TransformFiles, ItkDirectionAndCentre) {
  // The .tfm holds the fixed → moving map: the inverse of ours.
  const Transform t = known_affine();
  const std::string text = format_transform(t, TransformFormat::Itk);
  EXPECT_EQ(text.rfind("#Insight Transform File V1.0\n", 0), 0u);
  EXPECT_NE(text.find("Transform: AffineTransform_double_3_3\n"), std::string::npos);
  const Transform inv = t.inverse();
  std::istringstream in(text.substr(text.find("Parameters:") + 11));
  for (int k = 0; k < 12; ++k) {
    double v = 0;
    in >> v;
    const double expected = k < 9 ? inv.matrix()[k / 3][k % 3] : inv.matrix()[k - 9][3];
    EXPECT_EQ(v, expected) << k;
  }
  // A file with a centre: T(x) = A(x - c) + c + t maps fixed → moving.
  const std::string with_centre =
      "#Insight Transform File V1.0\n#Transform 0\nTransform: AffineTransform_double_3_3\n"
      "Parameters: 0 -1 0 1 0 0 0 0 1 1 2 3\nFixedParameters: 10 20 30\n";
  const Transform r = parse_transform(with_centre, TransformFormat::Itk, "c.tfm");
  EXPECT_EQ(r.kind(), TransformKind::Rigid);
  const Vec3 x{5, 6, 7};  // fixed point
  const Vec3 moving{0 * (5 - 10) - 1 * (6 - 20) + 10 + 1, 1 * (5 - 10) + 0 + 20 + 2, (7 - 30) + 30 + 3};
  const Vec3 back = r.apply(moving);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(back[k], x[k], 1e-12);
  EXPECT_THROW((void)parse_transform("#Insight Transform File V1.0\nTransform: BSplineTransform_double_3_3\n"
                                     "Parameters: 1 2 3\nFixedParameters: 0 0 0\n",
                                     TransformFormat::Itk, "b.tfm"),
               InputError);
  EXPECT_THROW((void)format_transform(Transform(Matrix3{{{1, 0, 0}, {0, 1, 0}, {0, 0, 0}}}, {0, 0, 0}), TransformFormat::Itk),
               InputError);
}

TEST(TransformFiles, PlainMatrixVariants) {
  const Transform a = parse_transform("# no kind here\n1 0 0 5\n0 1 0 6\n0 0 1 7\n0 0 0 1\n", TransformFormat::Matrix, "m.txt");
  EXPECT_EQ(a.kind(), TransformKind::Rigid);
  EXPECT_EQ(a.translation_part(), (Vec3{5, 6, 7}));
  const Transform b = parse_transform("2,0,0,0\n0,2,0,0\n0,0,2,1\n", TransformFormat::Matrix, "m.csv");
  EXPECT_EQ(b.kind(), TransformKind::Similarity);
  EXPECT_THROW((void)parse_transform("1 0 0\n", TransformFormat::Matrix, "m.txt"), InputError);
  EXPECT_THROW((void)parse_transform("1 0 0 0\n0 1 0 0\n0 0 1 0\n1 0 0 1\n", TransformFormat::Matrix, "m.txt"), InputError);
  write_text(scratch("kind.txt"), "# kind=affine\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n");
  EXPECT_EQ(read_transform(scratch("kind.txt")).kind(), TransformKind::Affine);
  EXPECT_THROW((void)read_transform(scratch("missing.txt")), InputError);
}

// The messages of malformed landmark and transform files: the file, the line where known, what is wrong.
// Found by fuzz_landmarks (fuzz/corpus/landmarks/amira_duplicate_block.txt): two coordinate
// declarations with the same @K overflowed the vector of sets (ASan heap-buffer-overflow); a huge
// 'define Markers' count overflowed 3·N.
TEST(LandmarkFiles, AmiraDuplicateBlockAndHugeCountAreRefused) {
  auto message = [](const std::string& text) -> std::string {
    try {
      (void)parse_landmarks(text, LandmarkFormat::Amira, "d.landmarkAscii");
    } catch (const InputError& e) {
      return e.what();
    }
    return "(no error)";
  };
  EXPECT_EQ(message("# AmiraMesh 3D ASCII 2.0\ndefine Markers 1\nMarkers { float[3] Coordinates } @1\n"
                    "Markers { float[3] Coordinates2 } @1\n@1\n1 2 3\n"),
            "d.landmarkAscii:4: data block @1 is declared twice");
  EXPECT_EQ(message("# AmiraMesh 3D ASCII 2.0\ndefine Markers 4000000000000000000\n"
                    "Markers { float[3] Coordinates } @1\n@1\n1 2 3\n"),
            "d.landmarkAscii:2: 'define Markers 4000000000000000000' declares more markers than a file of 105 bytes can hold");
  EXPECT_EQ(message("# AmiraMesh 3D ASCII 2.0\ndefine Markers 1\nMarkers { float[3] Coordinates } @-1\n@1\n1 2 3\n"),
            "d.landmarkAscii:3: expected a block number '@K' (K >= 0)");
  // fuzz/corpus/landmarks/amira_huge_numsets.txt: 'NumSets 1e300' was cast to int64 (UBSan).
  EXPECT_EQ(message("# AmiraMesh 3D ASCII 2.0\ndefine Markers 1\nParameters {\n NumSets 1e300\n}\n"
                    "Markers { float[3] Coordinates } @1\n@1\n1 2 3\n"),
            "d.landmarkAscii:4: expected 'NumSets k'");
  // fuzz/corpus/landmarks/amira_huge_data_block.txt: a data block '@1111111111111011111111' was cast
  // to int64 (UBSan); data blocks are checked like the declarations now.
  for (const char* block : {"@1111111111111011111111", "@-2", "@1.5"})
    EXPECT_EQ(message(std::string("# AmiraMesh 3D ASCII 2.0\ndefine Markers 1\nMarkers { float[3] Coordinates } @1\n") +
                      block + "\n7\n@1\n1 2 3\n"),
              "d.landmarkAscii:4: expected a block number '@K' (K >= 0)")
        << block;
}

// Found by fuzz_landmarks (fuzz/corpus/landmarks/csv_long_set_label.txt): a set label of 30 digits
// threw std::out_of_range from std::stoll (an uncaught exception, not an InputError). Such labels are
// names: the sets keep the order of their first appearance.
// A 30-digit set label used to throw std::out_of_range from std::stoll; digit strings of any length
// are ordered as numbers.
TEST(LandmarkFiles, CsvSetLabelsTooLongForAnInt64AreOrderedAsNumbers) {
  const LandmarkSet lm = parse_landmarks(
      "set,name,x,y,z\n111111111111111111111111111111,a,1,2,3\n5,a,4,5,6\n", LandmarkFormat::Csv, "long.csv");
  ASSERT_EQ(lm.set_count(), 2);
  EXPECT_EQ(lm.sets[0][0], (Vec3{4, 5, 6}));
  EXPECT_EQ(lm.sets[1][0], (Vec3{1, 2, 3}));
}

TEST(LandmarkFiles, MalformedFileMessages) {
  auto message = [](const std::function<void()>& f) -> std::string {
    try {
      f();
    } catch (const InputError& e) {
      return e.what();
    }
    return "(no error)";
  };
  EXPECT_EQ(message([] { (void)parse_landmarks("hello\n", LandmarkFormat::Amira, "x"); }),
            "x:1: not an AmiraMesh file (expected '# AmiraMesh 3D ASCII 2.0')");
  EXPECT_EQ(message([] { (void)parse_landmarks("1,2,3\n", LandmarkFormat::Fcsv, "nohdr.fcsv"); }),
            "nohdr.fcsv:1: expected at least 4 fields");
  EXPECT_EQ(
      message([] { (void)parse_landmarks("set,name,x,y,z\n0,a,1,2,3\n1,c,1,2,3\n", LandmarkFormat::Csv, "t.csv"); }),
      "t.csv: landmark 'c' of set 1 is not in set 0");
  EXPECT_EQ(message([] { (void)parse_landmarks("set,name,x,y\n", LandmarkFormat::Csv, "t.csv"); }),
            "t.csv:1: header has no 'z' column; expected set,name,x,y,z");
  EXPECT_EQ(message([] { (void)parse_landmarks("set,name,x,y,z\n0,a,1,zz,3\n", LandmarkFormat::Csv, "t.csv"); }),
            "t.csv:2: 'zz' is not a number");
  EXPECT_EQ(message([] { (void)resolve_landmark_format(LandmarkFormat::Auto, "x.txt"); }),
            "'x.txt': cannot tell the landmark format from the extension; use .landmarkAscii, .fcsv or .csv, or set "
            "'format'");
  EXPECT_EQ(message([] {
              (void)parse_transform(
                  "#Insight Transform File V1.0\nTransform: BSplineTransform_double_3_3\n"
                  "Parameters: 1 2 3\nFixedParameters: 0 0 0\n",
                  TransformFormat::Itk, "b.tfm");
            }),
            "b.tfm: ITK transform type 'BSplineTransform_double_3_3' is not supported; expected "
            "AffineTransform_double_3_3 (or _float_, or MatrixOffsetTransformBase)");
  EXPECT_EQ(message([] {
              (void)parse_transform(
                  "#Insight Transform File V1.0\nTransform: AffineTransform_double_3_3\n"
                  "Parameters: 1 0 0 0 1 0 0 0 1 0 0\nFixedParameters: 0 0 0\n",
                  TransformFormat::Itk, "p.tfm");
            }),
            "p.tfm:3: 'Parameters' has 11 numbers; expected 12");
  EXPECT_EQ(message([] { (void)parse_transform("1 0 0\n", TransformFormat::Matrix, "m.txt"); }),
            "m.txt: expected a 4x4 matrix (16 numbers, or 12 for the top 3 rows), found 3 numbers");
  EXPECT_EQ(
      message([] { (void)parse_transform("1 0 0 0\n0 1 0 0\n0 0 1 0\n1 0 0 1\n", TransformFormat::Matrix, "m.txt"); }),
      "m.txt: transform: the bottom row of a homogeneous matrix must be 0 0 0 1");
  EXPECT_EQ(message([] { (void)read_transform("/nonexistent/missing.txt"); }),
            "/nonexistent/missing.txt: file not found");
}

// Declared sizes are checked against the file before use, and huge numeric set labels do not throw
// std::out_of_range.
TEST(LandmarkFiles, DeclaredSizesAndHugeLabels) {
  auto message = [](const std::function<void()>& f) -> std::string {
    try {
      f();
    } catch (const InputError& e) {
      return e.what();
    }
    return "(no error)";
  };
  const std::string huge = "# AmiraMesh 3D ASCII 2.0\ndefine Markers 4000000000000000000\n"
                           "Markers { float[3] Coordinates } @1\n@1\n1 2 3\n";
  EXPECT_EQ(message([&] { (void)parse_landmarks(huge, LandmarkFormat::Amira, "h.landmarkAscii"); }),
            "h.landmarkAscii:2: 'define Markers 4000000000000000000' declares more markers than a file of " +
                std::to_string(huge.size()) + " bytes can hold");
  const auto lm = parse_landmarks("set,name,x,y,z\n100000000000000000000000,a,1,2,3\n2,a,4,5,6\n", LandmarkFormat::Csv, "l.csv");
  ASSERT_EQ(lm.set_count(), 2);
  EXPECT_EQ(lm.set(0)[0], (Vec3{4, 5, 6}));  // set "2" before the 24-digit one
}
