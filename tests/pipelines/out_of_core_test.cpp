// Out-of-core runs end to end: a pipeline under a tiny memory budget (block-wise median, Gaussian,
// threshold, chamfer, Euclidean DT, connected components, fill_cavities and illumination_z with their volumes in
// scratch files) writes the same bytes as the in-memory run, leaves no scratch file behind (also
// when a node fails), and an in-memory stage whose on-disk input does not fit the budget fails
// naming the node.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>

#include "skel/executor.hpp"
#include "skel/pipeline.hpp"

namespace fs = std::filesystem;
using namespace skel;

namespace {

fs::path scratch(const std::string& name) {
  fs::path d = fs::path(SKEL_BINARY_DIR) / "tests" / "scratch" / ("out_of_core_" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

std::string bytes_of(const fs::path& f) {
  std::ifstream in(f, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Every regular file under `dir`, relative to it.
std::vector<std::string> files_under(const fs::path& dir) {
  std::vector<std::string> r;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (e.is_regular_file()) r.push_back(fs::relative(e.path(), dir).string());
  std::sort(r.begin(), r.end());
  return r;
}

const char* kPipeline = R"(skelflow: 1
nodes:
  phantom: {module: synthetic.network, params: {shape: rods, size: [37, 29, 23], period: 12, radius: 3, noise: 0.1}}
  denoise: {module: segmentation.median, inputs: {image: phantom.image}}
  smooth: {module: segmentation.gaussian, inputs: {image: denoise.image}, params: {sigma: [1.0, 1.5, 0.7]}}
  seg: {module: segmentation.threshold, inputs: {image: smooth.image}, params: {method: otsu}}
  dist: {module: distance.chamfer, inputs: {mask: seg.mask}}
  save_mask: {module: io.write_volume, inputs: {volume: seg.mask}, params: {path: out/mask.h5}}
  save_dist: {module: io.write_volume, inputs: {volume: dist.distance}, params: {path: out/dist.h5}}
  edt: {module: distance.euclidean, inputs: {mask: seg.mask}}
  save_edt: {module: io.write_volume, inputs: {volume: edt.distance}, params: {path: out/edt.h5}}
  parts: {module: segmentation.connected_components, inputs: {mask: seg.mask}, params: {connectivity: 6}}
  save_labels: {module: io.write_volume, inputs: {volume: parts.labels}, params: {path: out/labels.h5}}
  save_table: {module: io.write_table, inputs: {table: parts.table}, params: {path: out/components.csv}}
  filled: {module: segmentation.fill_cavities, inputs: {mask: seg.mask}}
  save_filled: {module: io.write_volume, inputs: {volume: filled.mask}, params: {path: out/filled.h5}}
  lit: {module: segmentation.illumination_z, inputs: {image: phantom.image}, params: {percentile: 0.1}}
  save_lit: {module: io.write_volume, inputs: {volume: lit.image}, params: {path: out/lit.h5}}
  save_lit_table: {module: io.write_table, inputs: {table: lit.table}, params: {path: out/lit.csv}}
)";

RunReport run_into(const Pipeline& p, const fs::path& dir, uint64_t budget, Dims block = {0, 0, 0},
                   const fs::path& scratch_dir = {}) {
  ExecOptions o;
  o.output_dir = dir;
  o.memory_budget = budget;
  o.block = block;
  o.scratch_dir = scratch_dir;
  o.threads = 2;
  Executor ex;
  return ex.run(p, o);
}

}  // namespace

TEST(OutOfCore, TinyBudgetGivesTheSameBytesAndLeavesNoScratch) {
  const Pipeline p = Pipeline::parse(kPipeline, "ooc.yaml");
  const fs::path a = scratch("in_core"), b = scratch("odd_blocks"), c = scratch("budget_blocks");
  run_into(p, a, 0);
  run_into(p, b, 1ull << 20, {13, 17, 11});
  run_into(p, c, 1ull << 20);  // 16³ blocks from the budget
  const std::vector<std::string> outputs = {"out/components.csv", "out/dist.h5", "out/edt.h5", "out/filled.h5", "out/labels.h5",
                                            "out/lit.csv", "out/lit.h5", "out/mask.h5"};
  EXPECT_EQ(files_under(a), outputs);
  EXPECT_EQ(files_under(b), outputs);  // the scratch files went next to the outputs, and are gone
  EXPECT_EQ(files_under(c), outputs);
  for (const auto& f : outputs) {
    EXPECT_EQ(bytes_of(a / f), bytes_of(b / f)) << f;
    EXPECT_EQ(bytes_of(a / f), bytes_of(c / f)) << f;
  }
}

TEST(OutOfCore, BudgetFromThePipelineFileAndScratchFolder) {
  const Pipeline p = Pipeline::parse(std::string(kPipeline) + "execution: {memory_budget: 1MiB, block: [16, 13, 11]}\n", "ooc.yaml");
  const fs::path a = scratch("file_in_core"), b = scratch("file_budget"), s = scratch("file_scratch");
  run_into(Pipeline::parse(kPipeline, "ooc.yaml"), a, 0);
  // The statuses report blocks while the block-wise nodes run.
  ExecOptions o;
  o.output_dir = b;
  o.scratch_dir = s;
  std::vector<std::string> messages;
  std::mutex m;
  o.on_status = [&](const std::string& node, const NodeStatus& st) {
    std::lock_guard lock(m);
    if (st.state == NodeState::Running && !st.message.empty()) messages.push_back(node + ": " + st.message);
  };
  Executor ex;
  ex.run(p, o);
  for (const auto& f : {"out/components.csv", "out/dist.h5", "out/edt.h5", "out/filled.h5", "out/labels.h5", "out/lit.csv",
                        "out/lit.h5", "out/mask.h5"})
    EXPECT_EQ(bytes_of(a / f), bytes_of(b / f)) << f;
  EXPECT_TRUE(files_under(s).empty());
  EXPECT_NE(std::find(messages.begin(), messages.end(), "dist: chamfer 1/" + std::to_string(27 + 2 * 3 * 5 * 5) + " blocks"),
            messages.end());
}

TEST(OutOfCore, InMemoryStageOverTheBudgetFailsNamingTheNodeAndCleansUp) {
  std::string without_edt = std::string(kPipeline).substr(0, std::string(kPipeline).find("  edt:"));
  // save_dist writes the distance map through an in-memory stage (io.write_volume is block-wise).
  const std::string save_dist = "  save_dist: {module: io.write_volume, inputs: {volume: dist.distance}, params: {path: out/dist.h5}}\n";
  without_edt.replace(without_edt.find(save_dist), save_dist.size(),
                      "  save_dist: {module: volume.convert, inputs: {input: dist.distance}, params: {dtype: uint16}}\n");
  const Pipeline p = Pipeline::parse(without_edt, "ooc.yaml");
  const fs::path b = scratch("over_budget");
  // 30 KiB: the blocks and the mask fit, but volume.convert (in memory) cannot load the distance map.
  try {
    run_into(p, b, 30 << 10, {8, 8, 8});
    FAIL() << "no error";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("ooc.yaml:9:3: node 'save_dist' (volume.convert): input 'input': the volume on disk (volume.u16 "
                       "37x29x23, 48.2 KiB) does not fit the memory budget of 30 KiB"),
              std::string::npos)
        << msg;
  }
  EXPECT_TRUE(files_under(b).empty());  // no output, no scratch file
}

TEST(OutOfCore, GeodesicAndSkeletonGraphBlockwiseGiveTheSameFiles) {
  // geodesic.boundary_distance (margin d_max + t/2) and geometry.skeleton_to_graph (voxels gathered
  // with their 27-neighbourhoods) under a tiny budget with odd blocks: the same importance, surface,
  // graph (with radii), manifold volume and statistics as in memory.
  const Pipeline p = Pipeline::parse(R"(skelflow: 1
nodes:
  phantom: {module: synthetic.network, params: {shape: mixed, size: [33, 29, 27], period: 13, radius: 2.5, noise: 0.2}}
  seg: {module: segmentation.threshold, inputs: {image: phantom.image}, params: {low: 0.5}}
  geo: {module: geodesic.boundary_distance, inputs: {mask: seg.mask}, params: {threshold: 6}}
  save_imp: {module: io.write_volume, inputs: {volume: geo.importance}, params: {path: out/importance.h5}}
  save_surf: {module: io.write_volume, inputs: {volume: geo.surface_skeleton}, params: {path: out/surface.h5}}
  dist: {module: distance.chamfer, inputs: {mask: seg.mask}}
  skel: {module: thinning.lee94, inputs: {mask: seg.mask}}
  graph: {module: geometry.skeleton_to_graph, inputs: {skeleton: skel.skeleton, distance: dist.distance}, params: {with_manifold: true, smooth_passes: 1}}
  save_graph: {module: io.write_graph, inputs: {graph: graph.graph}, params: {path: out/graph.am}}
  save_manifold: {module: io.write_volume, inputs: {volume: graph.manifold}, params: {path: out/manifold.h5}}
  stats: {module: analysis.network_statistics, inputs: {graph: graph.graph}}
  save_stats: {module: io.write_table, inputs: {table: stats.summary}, params: {path: out/summary.csv}}
)", "ooc_geo.yaml");
  const fs::path a = scratch("geo_in_core"), b = scratch("geo_odd_blocks");
  run_into(p, a, 0);
  run_into(p, b, 1ull << 20, {11, 7, 9});
  const std::vector<std::string> outputs = {"out/graph.am", "out/importance.h5", "out/manifold.h5", "out/summary.csv",
                                            "out/surface.h5"};
  EXPECT_EQ(files_under(a), outputs);
  EXPECT_EQ(files_under(b), outputs);
  for (const auto& f : outputs) EXPECT_EQ(bytes_of(a / f), bytes_of(b / f)) << f;
  EXPECT_GT(bytes_of(a / "out/graph.am").size(), 200u);
  EXPECT_NE(bytes_of(a / "out/summary.csv").find("loop"), std::string::npos) << bytes_of(a / "out/summary.csv");
}
