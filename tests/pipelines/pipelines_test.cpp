// The shipped pipelines run end to end; the vessel pipeline recovers the phantom's ground truth; the
// bone pipelines write their meshes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "io/mesh_io.hpp"
#include "skel/executor.hpp"
#include "skel/mesh.hpp"
#include "skel/pipeline.hpp"
#include "skel/run_module.hpp"
#include "skel/spatial_graph.hpp"
#include "skel/table.hpp"

namespace fs = std::filesystem;
using namespace skel;

namespace {
fs::path pipeline(const std::string& name) { return fs::path(SKEL_SOURCE_DIR) / "pipelines" / name; }
fs::path scratch(const std::string& name) {
  fs::path d = fs::path(SKEL_BINARY_DIR) / "tests" / "scratch" / ("pipelines_" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}
}  // namespace

TEST(Pipelines, AllShippedPipelinesValidate) {
  for (const auto& e : fs::directory_iterator(fs::path(SKEL_SOURCE_DIR) / "pipelines")) {
    if (e.path().extension() != ".yaml") continue;
    SCOPED_TRACE(e.path().string());
    Pipeline p = Pipeline::load_file(e.path());
    auto ds = validate(p);
    for (const auto& d : ds) ADD_FAILURE() << d.format();
    // Canonical save and reload give the same pipeline.
    EXPECT_TRUE(Pipeline::parse(p.to_yaml()) == p);
  }
}

TEST(Pipelines, DemoRunsAndWritesItsOutputs) {
  const fs::path out = scratch("demo");
  Pipeline p = Pipeline::load_file(pipeline("demo.yaml"));
  Executor ex;
  ExecOptions o;
  o.output_dir = out;
  o.threads = 2;
  RunReport r = ex.run(p, o);
  EXPECT_TRUE(r.ok);
  for (const char* f : {"demo/image.h5", "demo/mask.h5", "demo/skeleton.h5", "demo/skeleton_topology.csv"})
    EXPECT_TRUE(fs::exists(out / f)) << f;
  EXPECT_NE(r.to_json().find("\"module\": \"thinning.doht\""), std::string::npos);
}

TEST(Pipelines, VesselPipelineRecoversTheGroundTruth) {
  Pipeline p = Pipeline::load_file(pipeline("vessel_network.yaml"));
  Executor ex;
  ExecOptions o;
  o.keep_outputs = true;
  o.threads = 2;
  o.output_dir = scratch("vessels");
  o.targets = {"stats", "phantom", "report"};  // the only file: the report
  ex.run(p, o);
  const fs::path report = o.output_dir / "vessels/report.html";
  ASSERT_TRUE(fs::exists(report));
  EXPECT_GT(fs::file_size(report), 10000u);  // histograms and the embedded MIP
  auto truth = std::dynamic_pointer_cast<const SpatialGraph>(ex.output(p, "phantom", "truth"));
  auto summary = std::dynamic_pointer_cast<const Table>(ex.output(p, "stats", "summary"));
  ASSERT_TRUE(truth && summary);
  const auto deg = truth->degrees();
  int64_t branch = 0, ends = 0;
  for (auto d : deg) {
    branch += d >= 3;
    ends += d == 1;
  }
  const double length = truth->total_length();
  const double rb = static_cast<double>(summary->ints("branch_points")[0]);
  const double re = static_cast<double>(summary->ints("end_points")[0]);
  const double rl = summary->reals("total_length")[0];
  std::printf("truth: %lld branch points, %lld end points, length %.1f; reconstruction: %.0f, %.0f, %.1f\n",
              static_cast<long long>(branch), static_cast<long long>(ends), length, rb, re, rl);
  EXPECT_LE(std::abs(rb - static_cast<double>(branch)), 0.05 * static_cast<double>(branch));
  EXPECT_LE(std::abs(re - static_cast<double>(ends)), std::max(1.0, 0.05 * static_cast<double>(ends)));
  EXPECT_LE(std::abs(rl - length), 0.05 * length);
}

// The float volumes of the vessel pipeline have one reader each (the distance map aside), so the executor frees each one after
// its only consumer: the phantom's image after the Gaussian (the report projects the mask), the
// Gaussian's output after the threshold. Before, the report read phantom.image and kept 4 bytes per
// voxel alive through the distance and thinning stages (15.1 bytes per voxel peak at 1024³).
TEST(Pipelines, VesselPipelineReadsEachFloatVolumeOnce) {
  const Pipeline p = Pipeline::load_file(pipeline("vessel_network.yaml"));
  std::map<std::string, std::vector<std::string>> readers;
  for (const PipelineNode& n : p.nodes())
    for (const auto& [port, from] : n.inputs) readers[from.str()].push_back(n.id + "." + port);
  EXPECT_EQ(readers["phantom.image"], (std::vector<std::string>{"smooth.image"}));
  EXPECT_EQ(readers["smooth.image"], (std::vector<std::string>{"seg.image"}));
  // In place (docs/architecture.md): the components are the thresholded mask's only reader and read
  // no label volume downstream; the mask's readers end with the thinning (the statistics and the
  // report read the distance map instead), so the skeleton can be thinned in the mask's buffer.
  EXPECT_EQ(readers["seg.mask"], (std::vector<std::string>{"largest.mask"}));
  EXPECT_TRUE(readers["largest.labels"].empty());
  std::vector<std::string> mask_readers = readers["largest.mask"];
  std::sort(mask_readers.begin(), mask_readers.end());
  EXPECT_EQ(mask_readers, (std::vector<std::string>{"distance.mask", "save_mask.volume", "skeleton.mask"}));
}

// The bone pipelines run end to end and write their meshes: the mixed skeleton's plates as
// triangles, its rods as lines, the 2 % decimation with the rod attachments kept; the curve
// skeletons as line meshes.
TEST(Pipelines, BonePipelinesWriteMeshes) {
  const fs::path out = scratch("bone_meshes");
  Executor ex;
  ExecOptions o;
  o.output_dir = out;
  o.threads = 2;
  o.keep_outputs = true;
  Pipeline plates = Pipeline::load_file(pipeline("bone_plates.yaml"));
  ASSERT_TRUE(ex.run(plates, o).ok);
  auto mesh = std::dynamic_pointer_cast<const Mesh>(ex.output(plates, "mesh_classes", "mesh"));
  auto small = std::dynamic_pointer_cast<const Mesh>(ex.output(plates, "mesh_small", "mesh"));
  ASSERT_TRUE(mesh && small);
  EXPECT_GT(mesh->triangle_count(), 10000);
  EXPECT_GT(mesh->line_count(), 0);
  EXPECT_LE(small->triangle_count(), mesh->triangle_count() * 3 / 100);
  EXPECT_GT(small->triangle_count(), 0);
  EXPECT_EQ(small->line_count(), mesh->line_count());
  const auto& cls = Mesh::attribute<int32_t>(mesh->triangle_attributes, "manifold");
  EXPECT_GT(std::count(cls.begin(), cls.end(), 1), mesh->triangle_count() / 2);  // mostly plate interiors
  // Rods and plates per element (fig. 6.14): the phantom has both; the mesh is coloured by them
  // (triangles are plate skeleton, lines rods, with few exceptions at the rod-plate junctions).
  auto indices = std::dynamic_pointer_cast<const Table>(ex.output(plates, "classes", "indices"));
  ASSERT_TRUE(indices);
  EXPECT_GT(indices->ints("plates")[0], 0);
  EXPECT_GT(indices->ints("rods")[0], 0);
  EXPECT_GT(indices->ints("rod_plate_junctions")[0], 0);
  EXPECT_GT(indices->reals("pBV_BV")[0], indices->reals("rBV_BV")[0]);
  const auto& tri_class = Mesh::attribute<int32_t>(mesh->triangle_attributes, "class");
  EXPECT_GT(std::count(tri_class.begin(), tri_class.end(), 2), mesh->triangle_count() * 9 / 10);
  const auto& line_class = Mesh::attribute<int32_t>(mesh->line_attributes, "class");
  EXPECT_GT(std::count(line_class.begin(), line_class.end(), 1), mesh->line_count() / 2);
  const auto& tri_element = Mesh::attribute<int32_t>(mesh->triangle_attributes, "element");
  EXPECT_EQ(std::count(tri_element.begin(), tri_element.end(), 0), 0);
  EXPECT_TRUE(fs::exists(out / "bone/structural_indices.csv"));
  EXPECT_TRUE(fs::exists(out / "bone/rod_plate_elements.csv"));
  const Mesh back = io::read_mesh(out / "bone/skeleton_mesh.ply", io::MeshFormat::ply);
  EXPECT_TRUE(back == *mesh);
  EXPECT_EQ(io::read_mesh(out / "bone/skeleton_mesh_2pct.vtp", io::MeshFormat::vtp).triangle_count(), small->triangle_count());
  EXPECT_TRUE(fs::exists(out / "bone/report.html"));

  Pipeline curve = Pipeline::load_file(pipeline("bone_curve.yaml"));
  ASSERT_TRUE(ex.run(curve, o).ok);
  auto lines = std::dynamic_pointer_cast<const Mesh>(ex.output(curve, "mesh_geodesic", "mesh"));
  ASSERT_TRUE(lines);
  EXPECT_GT(lines->line_count(), 10);
  EXPECT_LT(lines->triangle_count(), lines->line_count());  // a curve skeleton: lines, at most a few 2-cells
  for (const char* f : {"bone_curve/geodesic_guided_lines.vtp", "bone_curve/distance_ordered_lines.vtp", "bone_curve/bone_surface.stl"})
    EXPECT_TRUE(fs::exists(out / f)) << f;
}

// The "bring your own data" example: a 16-bit TIFF stack with ImageJ calibration in mm runs end to
// end, its outputs in the file's unit. The stack is the vessel phantom (data/README.md), so the
// reconstruction's total length matches the phantom's ground truth in mm.
TEST(Pipelines, VesselsFromTiffRunsInTheUnitOfTheFile) {
  const fs::path out = scratch("vessels_from_tiff");
  Pipeline p = Pipeline::load_file(pipeline("vessels_from_tiff.yaml"));
  Executor ex;
  ExecOptions o;
  o.output_dir = out;
  o.threads = 2;
  o.keep_outputs = true;
  RunReport r = ex.run(p, o);
  ASSERT_TRUE(r.ok) << r.error;
  for (const char* f : {"network.am", "network.vtp", "segments.csv", "summary.csv", "report.html"})
    EXPECT_TRUE(fs::exists(out / "vessels_from_tiff" / f)) << f;
  {
    std::ifstream in(out / "vessels_from_tiff" / "report.html");
    std::stringstream html;
    html << in.rdbuf();
    EXPECT_NE(html.str().find("segment length [mm]"), std::string::npos);  // the report speaks the file's unit
  }
  auto image = std::dynamic_pointer_cast<const VolumeU16>(ex.output(p, "image", "volume"));
  ASSERT_TRUE(image);
  EXPECT_EQ(image->unit(), "mm");
  EXPECT_EQ(image->spacing(), (Vec3{0.005, 0.005, 0.005}));
  EXPECT_EQ(image->dims(), (Dims{96, 96, 64}));
  // Ground truth of the same phantom, scaled to the file's 5 µm voxels.
  ParamMap truth_params{{"size", std::vector<int64_t>{96, 96, 64}}, {"seed", int64_t{3}}, {"roots", int64_t{4}},
                        {"noise", 0.0}, {"spacing", std::vector<double>{0.005, 0.005, 0.005}}};
  auto truth = run_module("synthetic.vessel_tree", {}, truth_params, {.threads = 2}).get<SpatialGraph>("truth");
  auto summary = std::dynamic_pointer_cast<const Table>(ex.output(p, "stats", "summary"));
  ASSERT_TRUE(summary);
  const double length = summary->reals("total_length")[0];
  EXPECT_NEAR(length, truth->total_length(), 0.1 * truth->total_length()) << "mm";
}

// pipelines/stitch_tiles.yaml: the four tiles of data/stitch_tiles/ (stage positions off by up to
// 5 µm) are placed back exactly: the merged volume is the phantom they were cut from
// (scripts/make_stitch_tiles.sh). Under a memory budget smaller than the merged volume the merge
// goes block by block onto disk and gives the same voxels.
TEST(Pipelines, StitchTilesMergesTheMosaicBackIntoThePhantom) {
  const fs::path out = scratch("stitch_tiles");
  Pipeline p = Pipeline::load_file(pipeline("stitch_tiles.yaml"));
  Executor ex;
  ExecOptions o;
  o.output_dir = out;
  o.threads = 2;
  o.keep_outputs = true;
  RunReport r = ex.run(p, o);
  ASSERT_TRUE(r.ok) << r.error;
  for (const char* f : {"merged.nrrd", "tiles.csv", "pairs.csv", "network.vtp"}) EXPECT_TRUE(fs::exists(out / "stitch_tiles" / f)) << f;
  ParamMap phantom_params{{"size", std::vector<int64_t>{88, 88, 32}}, {"seed", int64_t{5}}, {"roots", int64_t{4}},
                          {"noise", 0.03}, {"spacing", std::vector<double>{2, 2, 2}}};
  auto image = run_module("synthetic.vessel_tree", {}, phantom_params, {.threads = 2}).data("image");
  auto phantom = run_module("volume.convert", {{"input", image}},
                            {{"dtype", std::string("uint8")}, {"mode", std::string("rescale")}}, {.threads = 2})
                     .get<VolumeU8>("output");
  auto merged = std::dynamic_pointer_cast<const VolumeU8>(ex.output(p, "stitch", "volume"));
  ASSERT_TRUE(merged);
  ASSERT_EQ(merged->dims(), phantom->dims());
  EXPECT_EQ(merged->spacing(), (Vec3{2, 2, 2}));
  for (int64_t i = 0; i < merged->size(); ++i) ASSERT_EQ((*merged)[i], (*phantom)[i]) << "voxel " << i;
  auto pairs = std::dynamic_pointer_cast<const Table>(ex.output(p, "stitch", "pairs"));
  ASSERT_TRUE(pairs);
  EXPECT_EQ(pairs->rows(), 6);
  for (const auto& s : pairs->strings("status")) EXPECT_EQ(s, "used");

  // Out of core: a 64 KiB budget, the merged volume has 242 KiB: merged block by block onto disk,
  // then thresholded and labelled block-wise (io.write_volume is not block-wise yet); the components
  // table equals the one of the same pipeline in memory, and no scratch file is left.
  const std::string list = (fs::path(SKEL_SOURCE_DIR) / "data" / "stitch_tiles" / "tiles.csv").string();
  const Pipeline small = Pipeline::parse(
      "skelflow: 1\nnodes:\n  stitch: {module: registration.stitch_tiles, params: {tile_list: '" + list +
          "', search_radius: 6}}\n  seg: {module: segmentation.threshold, inputs: {image: stitch.volume}, params: {method: manual, low: 128}}\n"
          "  parts: {module: segmentation.connected_components, inputs: {mask: seg.mask}}\n"
          "  save: {module: io.write_table, inputs: {table: parts.table}, params: {path: parts.csv}}\n",
      "stitch_ooc.yaml");
  auto table_text = [&](uint64_t budget, const std::string& name) {
    const fs::path dir = scratch(name);
    ExecOptions b;
    b.output_dir = dir;
    b.threads = 2;
    b.memory_budget = budget;
    Executor ex2;
    RunReport r2 = ex2.run(small, b);
    EXPECT_TRUE(r2.ok) << r2.error;
    std::vector<std::string> left;
    for (const auto& e : fs::recursive_directory_iterator(dir)) left.push_back(e.path().filename().string());
    EXPECT_EQ(left, std::vector<std::string>{"parts.csv"}) << name;  // no scratch file left
    std::ifstream in(dir / "parts.csv");
    std::stringstream t;
    t << in.rdbuf();
    return t.str();
  };
  const std::string in_memory = table_text(0, "stitch_tiles_in_memory");
  EXPECT_GT(std::count(in_memory.begin(), in_memory.end(), '\n'), 1);
  EXPECT_EQ(table_text(64 * 1024, "stitch_tiles_out_of_core"), in_memory);
}
