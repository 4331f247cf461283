// The comparison pipelines run end to end: bone_compare finds the structures the after phantom lost
// (against the phantom's own `removed` ground truth) with few false alarms, and vessel_compare scores
// the reconstructed vessel graph against the phantom's ground truth.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "skel/executor.hpp"
#include "skel/pipeline.hpp"
#include "skel/spatial_graph.hpp"
#include "skel/table.hpp"
#include "skel/transform.hpp"
#include "skel/volume.hpp"

namespace fs = std::filesystem;
using namespace skel;

namespace {
fs::path pipeline(const std::string& name) { return fs::path(SKEL_SOURCE_DIR) / "pipelines" / name; }
fs::path scratch(const std::string& name) {
  fs::path d = fs::path(SKEL_BINARY_DIR) / "tests" / "scratch" / ("compare_pipelines_" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}
template <class T>
std::shared_ptr<const T> output(const Executor& ex, const Pipeline& p, const std::string& node, const std::string& port) {
  auto d = std::dynamic_pointer_cast<const T>(ex.output(p, node, port));
  if (!d) ADD_FAILURE() << "no output " << node << "." << port;
  return d;
}
std::string read_text(const fs::path& f) {
  std::ifstream in(f);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}
int64_t row_of(const Table& t, const std::string& level) {
  const auto& l = t.strings("level");
  for (size_t i = 0; i < l.size(); ++i)
    if (l[i] == level) return static_cast<int64_t>(i);
  ADD_FAILURE() << "no row " << level;
  return 0;
}
}  // namespace

TEST(ComparePipelines, BoneCompareFindsTheRemovedStructures) {
  const fs::path out = scratch("bone");
  Pipeline p = Pipeline::load_file(pipeline("bone_compare.yaml"));
  // A smaller phantom than the shipped 96³ (set on the pipeline, as `--set pair.size=...` does, so
  // that Executor::output finds the results under these parameters).
  p.set_param("pair", "size", std::vector<int64_t>{80, 80, 80});
  Executor ex;
  ExecOptions o;
  o.output_dir = out;
  o.keep_outputs = true;
  o.threads = 2;
  const RunReport r = ex.run(p, o);
  ASSERT_TRUE(r.ok) << r.error;
  for (const char* f : {"bone_compare/skeleton_distance.csv", "bone_compare/registration_residuals.csv",
                        "bone_compare/transform.txt", "bone_compare/before_skeleton_distance.vtp",
                        "bone_compare/changed.h5", "bone_compare/removed_truth.h5"})
    EXPECT_TRUE(fs::exists(out / f)) << f;

  auto skeleton = output<VolumeU8>(ex, p, "skeleton_before", "skeleton");
  auto changed = output<VolumeU8>(ex, p, "compare", "changed");
  auto removed = output<VolumeU8>(ex, p, "pair", "removed");
  auto table = output<Table>(ex, p, "compare", "table");
  auto fit = output<Transform>(ex, p, "register", "transform");
  auto truth = output<Transform>(ex, p, "pair", "transform");
  ASSERT_TRUE(skeleton && changed && removed && table && fit && truth);
  ASSERT_EQ(skeleton->dims(), removed->dims());
  ASSERT_EQ(changed->dims(), removed->dims());

  // Registration from 8 landmarks with picking noise (0.2 µm per coordinate in both scans): at the
  // corners of the volume, the fitted transform stays within half the change threshold (2 µm) of the
  // true one, so misregistration alone never makes a point "changed".
  double worst = 0;
  for (double x : {0.0, 79.0})
    for (double y : {0.0, 79.0})
      for (double z : {0.0, 79.0}) {
        const Vec3 a = fit->apply({x, y, z}), b = truth->apply({x, y, z});
        worst = std::max(worst, std::hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]));
      }
  EXPECT_LT(worst, 1.0);

  // Skeleton length (voxels) of the before skeleton inside / outside the lost material.
  int64_t removed_len = 0, found = 0, kept_len = 0, false_alarms = 0, changed_total = 0;
  for (int64_t i = 0; i < skeleton->size(); ++i) {
    changed_total += (*changed)[i] != 0;
    if (!(*skeleton)[i]) continue;
    if ((*removed)[i]) {
      ++removed_len;
      found += (*changed)[i] != 0;
    } else {
      ++kept_len;
      false_alarms += (*changed)[i] != 0;
    }
  }
  const double recall = static_cast<double>(found) / static_cast<double>(removed_len);
  const double false_alarm = static_cast<double>(false_alarms) / static_cast<double>(kept_len);
  std::printf("bone_compare 80³: registration error %.3f; removed skeleton %lld voxels, found %lld (recall %.3f); "
              "unchanged skeleton %lld voxels, false alarms %lld (%.3f)\n",
              worst, static_cast<long long>(removed_len), static_cast<long long>(found), recall,
              static_cast<long long>(kept_len), static_cast<long long>(false_alarms), false_alarm);
  ASSERT_GT(removed_len, 100);  // the phantom really lost structures
  EXPECT_GE(recall, 0.90);
  EXPECT_LE(false_alarm, 0.05);
  // The table reports the same changed points as the volume.
  EXPECT_EQ(table->strings("direction")[0], "reference_to_other");
  EXPECT_EQ(table->ints("changed_points")[0], changed_total);
  EXPECT_EQ(table->ints("points")[0], removed_len + kept_len);

  // The graph written for viewing carries the per-point distance and the changed flag.
  auto graph = output<SpatialGraph>(ex, p, "compare_graph", "graph");
  ASSERT_TRUE(graph);
  ASSERT_TRUE(graph->point_attributes.count("distance"));
  ASSERT_TRUE(graph->point_attributes.count("changed"));
  int64_t graph_changed = 0;
  for (const auto& edge : graph->point_attributes.at("changed"))
    for (float c : edge) graph_changed += c != 0;
  EXPECT_GT(graph_changed, 0);  // the removed structures are visible in the .vtp too
}

TEST(ComparePipelines, VesselCompareScoresTheReconstruction) {
  const fs::path out = scratch("vessel");
  Pipeline p = Pipeline::load_file(pipeline("vessel_compare.yaml"));
  Executor ex;
  ExecOptions o;
  o.output_dir = out;
  o.keep_outputs = true;
  o.threads = 2;
  const RunReport r = ex.run(p, o);
  ASSERT_TRUE(r.ok) << r.error;
  for (const char* f : {"vessel_compare/match.csv", "vessel_compare/netmets_errors.csv", "vessel_compare/truth_matched.vtp",
                        "vessel_compare/reconstruction_matched.vtp", "vessel_compare/truth_matched.am",
                        "vessel_compare/reconstruction_matched.am"})
    EXPECT_TRUE(fs::exists(out / f)) << f;
  const std::string csv = read_text(out / "vessel_compare/match.csv");
  EXPECT_NE(csv.find("f1"), std::string::npos) << csv;
  EXPECT_NE(csv.find("recall"), std::string::npos) << csv;

  auto table = output<Table>(ex, p, "match", "table");
  auto truth = output<SpatialGraph>(ex, p, "match", "reference_graph");
  auto recon = output<SpatialGraph>(ex, p, "match", "other_graph");
  ASSERT_TRUE(table && truth && recon);
  const auto& recall = table->reals("recall");
  const auto& precision = table->reals("precision");
  const auto& f1 = table->reals("f1");
  const int64_t n = row_of(*table, "nodes"), e = row_of(*table, "edges"), l = row_of(*table, "length");
  std::printf("vessel_compare: nodes P %.3f R %.3f F1 %.3f; edges P %.3f R %.3f F1 %.3f; length P %.3f R %.3f F1 %.3f\n",
              precision[n], recall[n], f1[n], precision[e], recall[e], f1[e], precision[l], recall[l], f1[l]);
  EXPECT_GT(recall[n], 0.8);
  EXPECT_GT(recall[e], 0.8);
  for (int64_t i : {n, e, l}) {
    EXPECT_NEAR(f1[i], 2 * precision[i] * recall[i] / (precision[i] + recall[i]), 1e-9);
  }
  // Unmatched elements are marked for the view.
  EXPECT_EQ(truth->edge_labels.at("matched").size(), static_cast<size_t>(truth->edge_count()));
  EXPECT_EQ(recon->node_labels.at("matched").size(), static_cast<size_t>(recon->node_count()));
}
