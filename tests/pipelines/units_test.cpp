// Units travel from the data to every output: a phantom in mm gives tables headed in mm, graph files
// that say mm and a run report that lists mm; a graph file in nm stays in nm through statistics.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "io/graph_io.hpp"
#include "skel/executor.hpp"
#include "skel/pipeline.hpp"
#include "skel/spatial_graph.hpp"
#include "skel/table.hpp"

namespace fs = std::filesystem;
using namespace skel;

namespace {
fs::path scratch(const std::string& name) {
  fs::path d = fs::path(SKEL_BINARY_DIR) / "tests" / "scratch" / ("units_" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}
std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}
std::string first_line(const fs::path& p) {
  const std::string t = slurp(p);
  return t.substr(0, t.find('\n'));
}
}  // namespace

TEST(Units, AVolumeInMillimetresGivesTablesAndGraphFilesInMillimetres) {
  const fs::path out = scratch("mm");
  const std::string yaml = R"(skelflow: 1
nodes:
  phantom: {module: synthetic.vessel_tree, params: {size: [64, 64, 48], seed: 3, roots: 2, spacing: [0.01, 0.01, 0.02], unit: mm}}
  seg: {module: segmentation.threshold, inputs: {image: phantom.image}, params: {method: manual, low: 0.5}}
  distance: {module: distance.euclidean, inputs: {mask: seg.mask}}
  skeleton: {module: thinning.doht, inputs: {mask: seg.mask, priority: distance.distance}}
  graph: {module: geometry.skeleton_to_graph, inputs: {skeleton: skeleton.skeleton, distance: distance.distance}}
  stats: {module: analysis.network_statistics, inputs: {graph: graph.graph, mask: seg.mask}}
  comps: {module: segmentation.connected_components, inputs: {mask: seg.mask}}
  save_summary: {module: io.write_table, inputs: {table: stats.summary}, params: {path: summary.csv}}
  save_segments: {module: io.write_table, inputs: {table: stats.segments}, params: {path: segments.csv}}
  save_components: {module: io.write_table, inputs: {table: comps.table}, params: {path: components.csv}}
  save_truth_edges: {module: io.write_table, inputs: {table: phantom.edges}, params: {path: truth_edges.csv}}
  save_am: {module: io.write_graph, inputs: {graph: graph.graph}, params: {path: graph.am}}
  save_vtp: {module: io.write_graph, inputs: {graph: graph.graph}, params: {path: graph.vtp}}
  save_graphml: {module: io.write_graph, inputs: {graph: graph.graph}, params: {path: graph.graphml}}
  save_csv: {module: io.write_graph, inputs: {graph: graph.graph}, params: {path: graph.csv, nodes_path: graph_nodes.csv}}
  save_tree: {module: io.write_graph, inputs: {graph: phantom.truth}, params: {path: truth.am}}
)";
  Pipeline p = Pipeline::parse(yaml);
  Executor ex;
  ExecOptions o;
  o.output_dir = out;
  o.threads = 2;
  const RunReport r = ex.run(p, o);
  ASSERT_TRUE(r.ok) << r.error;

  const std::string summary = first_line(out / "summary.csv");
  EXPECT_NE(summary.find("total_length [mm]"), std::string::npos) << summary;
  EXPECT_NE(summary.find("reference_volume [mm³]"), std::string::npos) << summary;
  EXPECT_NE(summary.find("length_density [mm⁻²]"), std::string::npos) << summary;
  const std::string segments = first_line(out / "segments.csv");
  EXPECT_NE(segments.find("length [mm]"), std::string::npos) << segments;
  EXPECT_NE(segments.find("mean_radius [mm]"), std::string::npos) << segments;
  EXPECT_NE(first_line(out / "components.csv").find("volume [mm³]"), std::string::npos);
  EXPECT_NE(first_line(out / "truth_edges.csv").find("length [mm]"), std::string::npos);
  EXPECT_NE(first_line(out / "graph.csv").find("x [mm]"), std::string::npos);
  EXPECT_NE(first_line(out / "graph_nodes.csv").find("x [mm]"), std::string::npos);
  // No output anywhere names the default unit.
  for (const auto& e : fs::recursive_directory_iterator(out))
    if (e.is_regular_file()) {
      EXPECT_EQ(slurp(e.path()).find("µm"), std::string::npos) << e.path();
    }

  EXPECT_NE(slurp(out / "graph.am").find("Coordinates \"mm\""), std::string::npos);
  EXPECT_NE(slurp(out / "truth.am").find("Coordinates \"mm\""), std::string::npos);
  // Every graph file reads back in mm.
  for (const char* f : {"graph.am", "graph.vtp", "graph.graphml", "graph.csv"}) {
    SCOPED_TRACE(f);
    const SpatialGraph g = io::read_graph(out / f, io::graph_format_from_path(f), out / "graph_nodes.csv");
    EXPECT_EQ(g.unit, "mm");
    EXPECT_GT(g.edge_count(), 0);
  }
  // The report lists the unit of every output that has one.
  const std::string json = r.to_json();
  EXPECT_NE(json.find("\"units\": {\"graph\": \"mm\"}"), std::string::npos);
  EXPECT_NE(json.find("\"mask\": \"mm\""), std::string::npos);
}

TEST(Units, AGraphReadInNanometresStaysInNanometresThroughStatistics) {
  const fs::path out = scratch("nm");
  SpatialGraph g;
  g.unit = "nm";
  g.add_node({0, 0, 0});
  g.add_node({300, 400, 0});
  g.add_edge(0, 1);
  io::write_graph(g, out / "neuron.graphml", io::GraphFormat::graphml);
  const std::string yaml = R"(skelflow: 1
nodes:
  read: {module: io.read_graph, params: {path: )" + (out / "neuron.graphml").string() + R"(}}
  stats: {module: analysis.network_statistics, inputs: {graph: read.graph}}
  save: {module: io.write_table, inputs: {table: stats.summary}, params: {path: summary.csv}}
)";
  Pipeline p = Pipeline::parse(yaml);
  Executor ex;
  ExecOptions o;
  o.output_dir = out;
  o.threads = 1;
  o.keep_outputs = true;
  const RunReport r = ex.run(p, o);
  ASSERT_TRUE(r.ok) << r.error;
  auto graph = std::dynamic_pointer_cast<const SpatialGraph>(ex.output(p, "read", "graph"));
  ASSERT_TRUE(graph);
  EXPECT_EQ(graph->unit, "nm");
  auto summary = std::dynamic_pointer_cast<const Table>(ex.output(p, "stats", "summary"));
  ASSERT_TRUE(summary);
  EXPECT_EQ(summary->column("total_length").unit, "nm");
  EXPECT_DOUBLE_EQ(summary->reals("total_length")[0], 500.0);
  EXPECT_NE(first_line(out / "summary.csv").find("total_length [nm]"), std::string::npos);
}
