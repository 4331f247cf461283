// The edit journal: parse_journal, then (when it parses) every entry is applied to a small graph the
// way graph.apply_edits replays it. The graph must stay valid after each entry.
#include "fuzz_common.hpp"
#include "graph/editor.hpp"
#include "skel/error.hpp"

namespace {
skel::SpatialGraph base_graph() {
  skel::SpatialGraph g;
  for (skel::Vec3 p : {skel::Vec3{0, 0, 0}, skel::Vec3{10, 0, 0}, skel::Vec3{20, 0, 0}, skel::Vec3{30, 5, 0},
                       skel::Vec3{30, -5, 0}, skel::Vec3{50, 50, 0}, skel::Vec3{52, 50, 0}})
    g.add_node(p);
  g.add_edge(0, 1, {{0, 0, 0}, {5, 0, 0}, {10, 0, 0}});
  g.add_edge(1, 2, {{10, 0, 0}, {15, 1, 0}, {20, 0, 0}});
  g.add_edge(2, 3);
  g.add_edge(2, 4);
  g.add_edge(5, 6);
  g.ensure_point_attribute("radius", 2.0f);
  g.ensure_edge_label("tree", 1);
  return g;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const skel::SpatialGraph base = base_graph();
  skel::graph::Journal journal;
  try {
    journal = skel::graph::parse_journal(skel::fuzz::as_text(data, size), "fuzz");
  } catch (const skel::Error&) {
    return 0;
  }
  skel::graph::GraphEditor editor(base);
  for (const auto& op : journal.ops) {
    (void)editor.apply(op, journal.tolerance);  // refusals are reported in the result, never thrown
    if (!editor.graph().check_invariants().empty()) std::abort();
  }
  return 0;
}
