// Writes the valid seeds of fuzz/corpus/ with Skelflow's own writers (run once when a format
// changes: build-fuzz/fuzz/fuzz_make_seeds fuzz/corpus). The broken seeds next to them are copies of
// tests/errors/data/files/ and hand-made truncations.
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "graph/editor.hpp"
#include "io/graph_io.hpp"
#include "io/hdf5_volume.hpp"
#include "io/landmark_io.hpp"
#include "io/volume_format.hpp"

using namespace skel;
namespace fs = std::filesystem;

namespace {
void put(const fs::path& file, const std::string& text) {
  fs::create_directories(file.parent_path());
  std::ofstream(file, std::ios::binary) << text;
}

SpatialGraph small_graph() {
  SpatialGraph g;
  for (Vec3 p : {Vec3{0, 0, 0}, Vec3{10, 0, 0}, Vec3{20, 0, 0}, Vec3{30, 5, 0}, Vec3{30, -5, 0}}) g.add_node(p);
  g.add_edge(0, 1, {{0, 0, 0}, {5, 0.5, 0}, {10, 0, 0}});
  g.add_edge(1, 2, {{10, 0, 0}, {15, 1, 0}, {20, 0, 0}});
  g.add_edge(2, 3);
  g.add_edge(2, 4);
  auto& r = g.ensure_point_attribute("radius", 2.0f);
  r[0][1] = 2.5f;
  g.ensure_edge_label("tree", 1);
  g.ensure_edge_attribute("weight")[1] = 0.5f;
  g.ensure_node_attribute("score")[2] = 3.0f;
  return g;
}
}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: fuzz_make_seeds CORPUS_DIR\n");
    return 2;
  }
  const fs::path dir = argv[1];
  const SpatialGraph g = small_graph();
  SpatialGraph tree;  // SWC holds trees only
  for (Vec3 p : {Vec3{0, 0, 0}, Vec3{10, 0, 0}, Vec3{20, 0, 0}, Vec3{30, 5, 0}}) tree.add_node(p);
  tree.add_edge(0, 1, {{0, 0, 0}, {5, 0.5, 0}, {10, 0, 0}});
  tree.add_edge(1, 2);
  tree.add_edge(1, 3);
  tree.ensure_point_attribute("radius", 1.5f);
  put(dir / "graph_amira/valid.am", io::graph_to_text(g, io::GraphFormat::amira));
  put(dir / "graph_vtp/valid.vtp", io::graph_to_text(g, io::GraphFormat::vtp, nullptr, {.encoding = io::VtpEncoding::ascii}));
  put(dir / "graph_vtp/valid_binary.vtp", io::graph_to_text(g, io::GraphFormat::vtp));  // appended raw, zlib
  put(dir / "graph_graphml/valid.graphml", io::graph_to_text(g, io::GraphFormat::graphml));
  put(dir / "graph_swc/valid.swc", io::graph_to_text(tree, io::GraphFormat::swc));
  std::string nodes;
  const std::string points = io::graph_to_text(g, io::GraphFormat::csv, &nodes);
  put(dir / "graph_csv/valid.csv", points + "\f" + nodes);

  LandmarkSet lm({{{1, 2, 3}, {4, 5, 6}, {7.5, 8, 9}}, {{1.5, 2, 3}, {4, 5.5, 6}, {7, 8, 9.5}}});
  put(dir / "landmarks/valid_amira.txt", "0" + io::format_landmarks(lm, io::LandmarkFormat::Amira));
  put(dir / "landmarks/valid.fcsv", "1" + io::format_landmarks(lm.single_set(0), io::LandmarkFormat::Fcsv));
  put(dir / "landmarks/valid.csv", "2" + io::format_landmarks(lm, io::LandmarkFormat::Csv));
  const Transform t = Transform::rotation({0, 0, 1}, 0.3);
  put(dir / "transform/valid_matrix.txt", "0" + io::format_transform(t, io::TransformFormat::Matrix));
  put(dir / "transform/valid.tfm", "1" + io::format_transform(Transform::scaling(1.5), io::TransformFormat::Itk));

  {
    graph::GraphEditor ed(g);
    const fs::path j = dir / "journal/valid.yaml";
    fs::create_directories(j.parent_path());
    fs::remove(j);
    ed.set_journal(j, 0.5);
    ed.split(0, 1);
    ed.connect(3, 4);
    ed.move_node(0, {0, 1, 0});
    ed.set_attribute(graph::Level::edge, {1}, "radius", 3);
    ed.undo();
    ed.redo();
    ed.merge(1);
    ed.prune(4);
    ed.delete_components(1);
    ed.bridge_gaps(5);
    ed.delete_edges({0});
  }
  Volume<uint8_t> v(Dims{6, 5, 4}, 0, {0.5, 0.5, 1}, {1, 2, 3});
  v(2, 2, 2) = 1;
  io::write_volume(dir / "hdf5/valid_u8.h5", v);
  Volume<float> f(Dims{3, 3, 3}, 1.5f);
  io::write_volume(dir / "hdf5/valid_f32.h5", f);
  // The single-file formats of the volume registry, raw and compressed.
  Volume<uint16_t> w(Grid(Dims{5, 4, 3}, {0.5, 0.75, 2}, {-1, 2, 3}, "mm"), 0);
  for (int64_t i = 0; i < w.size(); ++i) w[i] = static_cast<uint16_t>(i * 331);
  for (const auto& [format, ext] : {std::pair{"nrrd", ".nrrd"}, {"metaimage", ".mha"}, {"nifti", ".nii"}, {"vti", ".vti"},
                                    {"amira", ".am"}}) {
    fs::create_directories(dir / ("volume_" + std::string(format)));
    for (int c : {0, 1}) {
      io::VolumeWriteOptions o;
      o.compression = c;
      io::write_any_volume(dir / ("volume_" + std::string(format)) / ("valid_u16_" + std::to_string(c) + ext), w, o);
      io::write_any_volume(dir / ("volume_" + std::string(format)) / ("valid_u8_" + std::to_string(c) + ext), v, o);
    }
  }
  return 0;
}
