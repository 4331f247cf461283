// Graph editing: exact undo/redo under 10^4 random operations, invariants after every step, the
// journal's format and its replay on a perturbed reconstruction, dangling-end partners.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <random>

#include "graph/editor.hpp"

using namespace skel;
using namespace skel::graph;
namespace fs = std::filesystem;

namespace {

// A random graph with polylines and attributes of every kind.
SpatialGraph random_graph(uint64_t seed, int nodes, int edges) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 100);
  SpatialGraph g;
  for (int i = 0; i < nodes; ++i) g.add_node({u(rng), u(rng), u(rng)});
  std::uniform_int_distribution<int> pick(0, nodes - 1), np(0, 4);
  for (int i = 0; i < edges; ++i) {
    const int a = pick(rng), b = pick(rng);
    std::vector<Vec3> pts{g.positions[a]};
    const int k = np(rng);
    for (int j = 1; j <= k; ++j) {
      const double f = static_cast<double>(j) / (k + 1);
      pts.push_back({g.positions[a][0] * (1 - f) + g.positions[b][0] * f + u(rng) * 0.02,
                     g.positions[a][1] * (1 - f) + g.positions[b][1] * f, g.positions[a][2] * (1 - f) + g.positions[b][2] * f});
    }
    pts.push_back(g.positions[b]);
    g.add_edge(a, b, pts);
  }
  auto& r = g.ensure_point_attribute("radius");
  for (auto& v : r)
    for (auto& x : v) x = static_cast<float>(1.0 + u(rng) / 50);
  auto& t = g.ensure_edge_label("tree");
  for (auto& x : t) x = static_cast<int32_t>(pick(rng) % 3);
  auto& w = g.ensure_edge_attribute("weight");
  for (auto& x : w) x = static_cast<float>(u(rng));
  auto& nl = g.ensure_node_attribute("score");
  for (auto& x : nl) x = static_cast<float>(u(rng));
  return g;
}

SpatialGraph chain_graph() {
  // a - b - c (b of degree 2), c - d and c - e (c a junction), f isolated segment f - g
  SpatialGraph g;
  for (Vec3 p : {Vec3{0, 0, 0}, Vec3{10, 0, 0}, Vec3{20, 0, 0}, Vec3{30, 5, 0}, Vec3{30, -5, 0}, Vec3{50, 50, 0},
                 Vec3{52, 50, 0}})
    g.add_node(p);
  g.add_edge(0, 1, {{0, 0, 0}, {5, 0, 0}, {10, 0, 0}});
  g.add_edge(1, 2);
  g.add_edge(2, 3);
  g.add_edge(2, 4);
  g.add_edge(5, 6);
  auto& r = g.ensure_point_attribute("radius", 2.0f);
  (void)r;
  return g;
}

void expect_valid(const GraphEditor& ed) {
  const auto p = ed.graph().check_invariants();
  ASSERT_TRUE(p.empty()) << p.front();
}

}  // namespace

TEST(GraphEditor, RandomOperationsUndoRedoExactly) {
  const SpatialGraph original = random_graph(42, 120, 180);
  GraphEditor ed(original);
  std::mt19937_64 rng(7);
  int ops = 0, refused = 0;
  for (int step = 0; step < 10000; ++step) {
    const SpatialGraph& g = ed.graph();
    const int64_t nn = g.node_count(), ne = g.edge_count();
    auto rnd = [&](int64_t n) { return static_cast<int64_t>(rng() % static_cast<uint64_t>(std::max<int64_t>(n, 1))); };
    int which = static_cast<int>(rng() % 10);
    // Keep the graph populated: more edges when few, more nodes (splits) when few.
    if (ne < 150 && (which == 0 || which == 1 || which == 4)) which = rng() % 2 ? 2 : 3;
    if (nn < 80 && (which == 1 || which == 2 || which == 4)) which = 3;
    const size_t before = ed.undo_count();
    try {
      switch (which) {
        case 0: ed.delete_edges({rnd(ne), rnd(ne)}); break;
        case 1: ed.delete_node(rnd(nn)); break;
        case 2:
          if (rng() % 2) {
            const int64_t e = rnd(ne);
            ed.connect(rnd(nn), -1, e, rnd(static_cast<int64_t>(g.edges[e].points.size())));
          } else {
            ed.connect(rnd(nn), rnd(nn));
          }
          break;
        case 3: {  // split an edge that has an interior point, else add a 3-point edge
          const int64_t e = rnd(ne);
          const int64_t np = static_cast<int64_t>(g.edges[e].points.size());
          if (np >= 3) ed.split(e, 1 + rnd(np - 2));
          else ed.connect(rnd(nn), -1, e, 0);
          break;
        }
        case 4: {  // merge a node of degree 2 if there is one
          const auto deg = g.degrees();
          std::vector<int64_t> two;
          for (int64_t n = 0; n < nn; ++n)
            if (deg[n] == 2) two.push_back(n);
          ed.merge(two.empty() ? rnd(nn) : two[static_cast<size_t>(rnd(static_cast<int64_t>(two.size())))]);
          break;
        }
        case 5: ed.move_node(rnd(nn), {static_cast<double>(rnd(100)), static_cast<double>(rnd(100)), 3.5}); break;
        case 6: {
          const bool node = rng() % 2;
          ed.set_attribute(node ? Level::node : Level::edge, {rnd(node ? nn : ne)}, rng() % 3 ? "radius" : "new_attr", 3.0);
          break;
        }
        case 7: ed.prune(4.0); break;
        case 8: ed.delete_components(2.0); break;
        default: ed.bridge_gaps(10.0); break;
      }
    } catch (const Error&) {
      ++refused;  // an impossible choice (a loop to merge, a self-connection) leaves the graph unchanged
    }
    if (ed.undo_count() > before) ++ops;
    expect_valid(ed);
    if (step % 97 == 0) ed.undo();  // some undos in between
  }
  std::printf("%d steps applied, %d refused\n", ops, refused);
  EXPECT_GT(ops, 9000);
  const SpatialGraph final_state = ed.graph();
  EXPECT_GT(final_state.edge_count(), 50);
  const size_t steps = ed.undo_count();
  while (ed.undo()) expect_valid(ed);
  EXPECT_TRUE(same_graph(ed.graph(), original));
  while (ed.redo()) expect_valid(ed);
  EXPECT_TRUE(same_graph(ed.graph(), final_state));
  EXPECT_EQ(ed.undo_count(), steps);
}

TEST(GraphEditor, OperationsDoWhatTheySay) {
  GraphEditor ed(chain_graph());
  // merge b: a - c becomes one edge with the joined polyline
  ed.merge(1);
  EXPECT_EQ(ed.graph().node_count(), 6);
  EXPECT_EQ(ed.graph().edge_count(), 4);
  const int64_t a_c = ed.edge_at({15, 0, 0}, 0.1);
  ASSERT_GE(a_c, 0);
  EXPECT_DOUBLE_EQ(ed.graph().edge_length(a_c), 20.0);
  EXPECT_EQ(ed.graph().edges[a_c].points.size(), 4u);
  // split it again at (10, 0, 0)
  int64_t pt = -1;
  const int64_t e = ed.edge_at({10, 0, 0}, 0.1, &pt);
  ed.split(e, pt);
  EXPECT_EQ(ed.graph().node_count(), 7);
  EXPECT_GE(ed.node_at({10, 0, 0}, 0.01), 0);
  // move a node: its polylines follow, the far ends stay
  const int64_t n = ed.node_at({10, 0, 0}, 0.01);
  ed.move_node(n, {10, 4, 0});
  expect_valid(ed);
  EXPECT_GE(ed.node_at({10, 4, 0}, 1e-9), 0);
  EXPECT_GE(ed.node_at({0, 0, 0}, 1e-9), 0);
  // prune: spurs c-d and c-e (length ~11.2) go; c is left with degree 1 (no merge needed)
  ed.prune(12.0);
  EXPECT_EQ(ed.node_at({30, 5, 0}, 0.1), -1);
  // delete the small isolated component
  ed.delete_components(5.0);
  EXPECT_EQ(ed.node_at({50, 50, 0}, 0.1), -1);
  expect_valid(ed);
  // set a radius on an edge: every point gets it
  const int64_t e2 = ed.edge_at({5, 2, 0}, 3.0);
  ed.set_attribute(Level::edge, {e2}, "radius", 7.5);
  for (float r : ed.graph().point_attributes.at("radius")[e2]) EXPECT_FLOAT_EQ(r, 7.5f);
  EXPECT_EQ(ed.undo_text().rfind("{op: set", 0), 0u);
}

TEST(GraphEditor, ConnectToAnEdgePointSplitsIt) {
  GraphEditor ed(chain_graph());
  const int64_t f = ed.node_at({50, 50, 0}, 0.1);
  const int64_t e = ed.edge_at({5, 0, 0}, 0.1);
  ed.connect(f, -1, e, 1);  // the interior point (5, 0, 0)
  const int64_t m = ed.node_at({5, 0, 0}, 1e-9);
  ASSERT_GE(m, 0);
  EXPECT_EQ(ed.graph().degrees()[m], 3);
  // The new edge's radius is interpolated from its two ends (2 at both).
  const int64_t ne = ed.graph().edge_count() - 1;
  for (float r : ed.graph().point_attributes.at("radius")[ne]) EXPECT_FLOAT_EQ(r, 2.0f);
  EXPECT_THROW(ed.connect(f, f), Error);
  expect_valid(ed);
}

TEST(GraphEditor, RoutedConnectFollowsTheMask) {
  // An L-shaped tube: the straight line between its ends leaves the mask, the route must not.
  auto mask = std::make_shared<VolumeU8>(Dims{30, 30, 3}, 0);
  for (int x = 2; x < 28; ++x) (*mask)(x, 2, 1) = 1;
  for (int y = 2; y < 28; ++y) (*mask)(27, y, 1) = 1;
  SpatialGraph g;
  g.add_node({2, 2, 1});
  g.add_node({27, 27, 1});
  EditContext ctx;
  ctx.mask = mask;
  GraphEditor ed(g, ctx);
  ed.connect(0, 1, -1, -1, Route::mask);
  const auto& pts = ed.graph().edges[0].points;
  for (const auto& p : pts)
    EXPECT_TRUE((*mask)(static_cast<int64_t>(std::lround(p[0])), static_cast<int64_t>(std::lround(p[1])), 1)) << p[0] << " " << p[1];
  EXPECT_NEAR(ed.graph().edge_length(0), 50.0, 1.0);
}

TEST(GraphEditor, JournalIsAppendedAndReplaysOnAPerturbedGraph) {
  const fs::path dir = fs::path(SKEL_BINARY_DIR) / "tests" / "scratch" / "editing";
  fs::remove_all(dir);
  const fs::path jp = dir / "edits.yaml";
  SpatialGraph base = random_graph(3, 60, 80);
  GraphEditor ed(base);
  ed.set_journal(jp, 0.5);
  ed.delete_edges({3});
  ed.connect(1, 2);
  ed.move_node(5, {1, 2, 3});
  ed.set_attribute(Level::edge, {7}, "tree", 2);
  ed.undo();
  ed.redo();
  int64_t split_edge = 10;
  ed.split(split_edge, 1 + 0 * static_cast<int64_t>(ed.graph().edges[split_edge].points.size()));
  // Every step is on disk already (flushed), as a valid journal.
  Journal j = read_journal(jp);
  ASSERT_EQ(j.ops.size(), 7u);
  EXPECT_EQ(j.ops[4].op, EditKind::undo);
  EXPECT_DOUBLE_EQ(j.tolerance, 0.5);

  // Replay on the same graph: identical result.
  GraphEditor same(base);
  for (const auto& op : j.ops) EXPECT_TRUE(same.apply(op, j.tolerance).applied) << op.to_yaml();
  EXPECT_TRUE(same_graph(same.graph(), ed.graph()));

  // Replay on a "recomputed" graph: positions shifted by 0.1, and the edge the journal deletes is
  // gone already. Everything else applies; the missing target is reported.
  SpatialGraph moved = base;
  for (auto& p : moved.positions) p[0] += 0.1;
  for (auto& e : moved.edges)
    for (auto& p : e.points) p[0] += 0.1;
  moved.remove_edge(3);
  GraphEditor re(moved);
  int not_applied = 0;
  std::string msg;
  for (const auto& op : j.ops) {
    auto r = re.apply(op, j.tolerance);
    if (!r.applied) {
      ++not_applied;
      msg = r.message;
    }
  }
  EXPECT_EQ(not_applied, 1);
  EXPECT_NE(msg.find("no edge within 0.5"), std::string::npos) << msg;
}

TEST(GraphEditor, PruneRelativeToTheRadiusAtTheJunctionAndInTheJournal) {
  // Trunk (0,0,0)-(10,0,0)-(20,0,0) of radius 4 with two spurs at the junction: 6 long (stored from
  // its free end to the junction) and 12 long.
  SpatialGraph g;
  g.add_node({0, 0, 0});
  g.add_node({10, 0, 0});
  g.add_node({20, 0, 0});
  g.add_node({10, 6, 0});
  g.add_node({10, -12, 0});
  g.add_edge(0, 1);
  g.add_edge(1, 2);
  g.add_edge(3, 1, {{10, 6, 0}, {10, 0, 0}});
  g.add_edge(1, 4, {{10, 0, 0}, {10, -12, 0}});
  auto& r = g.ensure_point_attribute("radius");
  r[0] = {4.0f, 4.0f};
  r[1] = {4.0f, 4.0f};
  r[2] = {1.0f, 4.0f};  // 4 at the junction end
  r[3] = {4.0f, 1.0f};
  {
    GraphEditor ed{SpatialGraph(g)};
    ed.prune(5.0);  // absolute length only: both spurs stay
    EXPECT_EQ(ed.graph().edge_count(), 4);
  }
  GraphEditor ed{SpatialGraph(g)};
  const EditOp op = ed.prune(5.0, 2.0);  // limit 8: the 6-long spur goes, the 12-long one stays
  expect_valid(ed);
  EXPECT_EQ(ed.node_at({10, 6, 0}, 0.1), -1);
  EXPECT_GE(ed.node_at({10, -12, 0}, 0.1), 0);
  EXPECT_EQ(ed.graph().edge_count(), 3);
  ed.undo();
  EXPECT_EQ(ed.graph().edge_count(), 4);
  // The journal line carries the factor and replays the same way.
  EXPECT_EQ(op.to_yaml(), "{op: prune, max_length: 5, radius_factor: 2}");
  const Journal j = parse_journal("skelflow_edits: 1\nops:\n- " + op.to_yaml() + "\n");
  ASSERT_EQ(j.ops.size(), 1u);
  EXPECT_DOUBLE_EQ(j.ops[0].radius_factor, 2.0);
  GraphEditor replay{SpatialGraph(g)};
  EXPECT_TRUE(replay.apply(j.ops[0], 1.0).applied);
  EXPECT_EQ(replay.graph().edge_count(), 3);
  // Without radii the factor is an error, reported by replay instead of applied.
  SpatialGraph bare = g;
  bare.point_attributes.clear();
  GraphEditor nr{std::move(bare)};
  EXPECT_THROW(nr.prune(5.0, 2.0), InputError);
  const ApplyResult res = nr.apply(j.ops[0], 1.0);
  EXPECT_FALSE(res.applied);
  EXPECT_NE(res.message.find("'radius'"), std::string::npos) << res.message;
  EXPECT_THROW(parse_journal("skelflow_edits: 1\nops:\n- {op: prune, max_length: 1, radius_factor: -1}\n"),
               InputError);
}

TEST(GraphEditor, MalformedJournalNamesLine) {
  try {
    parse_journal("skelflow_edits: 1\nops:\n- {op: delete_edge}\n", "j.yaml");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("j.yaml:3:3: op delete_edge needs 'at'"), std::string::npos) << e.what();
  }
  EXPECT_THROW(parse_journal("skelflow_edits: 1\nops:\n- {op: explode}\n"), InputError);
  EXPECT_THROW(parse_journal("hello: 1\n"), InputError);
}

// A journal whose session was killed after the header and before its first operation replays as no
// operations (before: "j.yaml:6:1: 'ops' must be a list"; found by the SIGKILL crash-safety test).
TEST(GraphEditor, JournalWithNoOperationsYetIsEmpty) {
  const std::string header = "# Skelflow edit journal\nskelflow_edits: 1\ntolerance: 1\nops:\n";
  EXPECT_TRUE(parse_journal(header, "j.yaml").ops.empty());
  EXPECT_EQ(parse_journal(header, "j.yaml").tolerance, 1.0);
  EXPECT_THROW(parse_journal("skelflow_edits: 1\nops: 3\n", "j.yaml"), InputError);
}

// A kill can cut the editor's one-line append short (found by the SIGKILL test in CI: "edits_47.yaml:71:1:
// YAML syntax error: end of sequence flow not found"). The cut last line is left out and named; a
// whole last entry without its newline is kept; an error before the last line is still an error;
// appending to such a journal first cuts the broken line off (or ends the whole one with a newline).
TEST(GraphEditor, JournalWithALastLineCutShortReadsTheEntriesBeforeIt) {
  const std::string header = "# Skelflow edit journal\nskelflow_edits: 1\ntolerance: 0.5\nops:\n";
  const std::string e1 = "- {op: connect, from: [1, 2, 3], to: [4, 5, 6]}\n", e2 = "- {op: undo}\n";
  const std::string torn = "- {op: move_node, from: [1, 2, 3], to: [1.5, 2";
  const Journal j = parse_journal(header + e1 + e2 + torn, "j.yaml");
  ASSERT_EQ(j.ops.size(), 2u);
  EXPECT_EQ(j.ops[0].op, EditKind::connect);
  EXPECT_EQ(j.ops[1].op, EditKind::undo);
  EXPECT_DOUBLE_EQ(j.tolerance, 0.5);
  EXPECT_NE(j.dropped.find("j.yaml:7: the last line is incomplete"), std::string::npos) << j.dropped;
  EXPECT_NE(j.dropped.find(torn), std::string::npos) << j.dropped;
  // Cut anywhere inside the last entry: always the two entries before it.
  const std::string whole = "- {op: move_node, from: [1, 2, 3], to: [1.5, 2, 3]}";
  for (size_t n = 1; n < whole.size(); ++n) {
    const Journal c = parse_journal(header + e1 + e2 + whole.substr(0, n), "j.yaml");
    EXPECT_EQ(c.ops.size(), 2u) << n;
  }
  // Only the newline missing: the entry is whole and kept.
  const Journal k = parse_journal(header + e1 + e2 + whole, "j.yaml");
  ASSERT_EQ(k.ops.size(), 3u);
  EXPECT_EQ(k.ops[2].op, EditKind::move_node);
  EXPECT_TRUE(k.dropped.empty());
  // An error before the last line is reported as before, not hidden by the cut line.
  try {
    parse_journal(header + "- {op: delete_edge}\n" + torn, "j.yaml");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("j.yaml:5:3: op delete_edge needs 'at'"), std::string::npos) << e.what();
  }

  // Appending: the editor cuts the broken line off before its first entry.
  const fs::path dir = fs::path(SKEL_BINARY_DIR) / "tests" / "scratch" / "editing_cut";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const SpatialGraph base = random_graph(5, 20, 20);
  auto write = [](const fs::path& p, const std::string& text) {
    std::ofstream o(p, std::ios::binary);
    o << text;
  };
  const fs::path jp = dir / "edits.yaml";
  write(jp, header + e2 + torn);
  {
    GraphEditor ed(base);
    ed.set_journal(jp, 0.5);
    ed.move_node(1, {7, 8, 9});
  }
  Journal a = read_journal(jp);
  EXPECT_TRUE(a.dropped.empty()) << a.dropped;
  ASSERT_EQ(a.ops.size(), 2u);
  EXPECT_EQ(a.ops[0].op, EditKind::undo);
  EXPECT_EQ(a.ops[1].op, EditKind::move_node);
  // A whole last entry without its newline: kept, and the next entry goes on its own line.
  write(jp, header + e2 + "- {op: redo}");
  {
    GraphEditor ed(base);
    ed.set_journal(jp, 0.5);
    ed.move_node(2, {7, 8, 9});
  }
  a = read_journal(jp);
  ASSERT_EQ(a.ops.size(), 3u);
  EXPECT_EQ(a.ops[1].op, EditKind::redo);
  EXPECT_EQ(a.ops[2].op, EditKind::move_node);
}

TEST(DanglingEnds, FindsFacingEndsAndEdgePoints) {
  SpatialGraph g;
  // Segment A ends at (10,0,0) pointing +x; segment B starts at (13,0,0) continuing +x: a gap of 3.
  g.add_node({0, 0, 0});
  g.add_node({10, 0, 0});
  g.add_node({13, 0, 0});
  g.add_node({25, 0, 0});
  g.add_edge(0, 1);
  g.add_edge(2, 3);
  // Segment C ends at (5, 4, 0) pointing -y towards the middle of A.
  g.add_node({5, 12, 0});
  g.add_node({5, 4, 0});
  g.add_edge(4, 5, {{5, 12, 0}, {5, 8, 0}, {5, 4, 0}});
  DanglingOptions o;
  o.max_distance = 6;
  auto ends = find_dangling_ends(g, o);
  ASSERT_EQ(ends.size(), 6u);
  // Best: the facing ends 1 and 2 (distance 3, angle 0, score 3 * 0.8).
  EXPECT_TRUE(ends[0].has_partner && ends[0].partner_is_node);
  EXPECT_DOUBLE_EQ(ends[0].distance, 3.0);
  EXPECT_NEAR(ends[0].score, 2.4, 1e-12);
  // C's end finds the point of A below it? A has only its two end points, so C finds nothing within
  // 60 degrees... add an interior point to A and it does.
  g.edges[0].points = {{0, 0, 0}, {5, 0, 0}, {10, 0, 0}};
  ends = find_dangling_ends(g, o);
  bool found = false;
  for (const auto& d : ends)
    if (d.node == 5) {
      found = d.has_partner && !d.partner_is_node && d.partner_edge == 0 && d.partner_point == 1;
      EXPECT_DOUBLE_EQ(d.distance, 4.0);
    }
  EXPECT_TRUE(found);
  GraphEditor ed(g);
  ed.bridge_gaps(6.0);
  EXPECT_EQ(ed.graph().connected_components(), 1);
}

// The messages of malformed journals: the file, line and column, and what is wrong.
TEST(GraphEditor, MalformedJournalMessages) {
  auto message = [](const std::string& text) -> std::string {
    try {
      (void)parse_journal(text, "j.yaml");
    } catch (const InputError& e) {
      return e.what();
    }
    return "(no error)";
  };
  EXPECT_EQ(message("skelflow_edits: 1\nops:\n- {op: explode}\n"),
            "j.yaml:3:8: unknown op 'explode' (expected one of delete_edge, delete_node, connect, split, merge, "
            "move_node, set, prune, delete_components, bridge_gaps, undo, redo)");
  EXPECT_EQ(message("hello: 1\n"), "j.yaml: not an edit journal (expected 'skelflow_edits: 1' and 'ops:')");
  EXPECT_EQ(message("skelflow_edits: 2\n"),
            "j.yaml:1:17: unsupported journal version '2' (this Skelflow reads version 1)");
  EXPECT_EQ(message("skelflow_edits: 1\nops: [\n"), "j.yaml:3:1: YAML syntax error: end of sequence flow not found");
  EXPECT_EQ(message("skelflow_edits: 1\ntolerance: wide\n"), "j.yaml:2:12: 'tolerance' must be a number, got 'wide'");
  EXPECT_EQ(message("skelflow_edits: 1\nops:\n- {op: prune, max_length: long}\n"),
            "j.yaml:3:27: 'max_length' must be a number, got 'long'");
  EXPECT_EQ(message("skelflow_edits: 1\nops:\n- {op: connect, from: [0, 0, 0], to: [1, 1, 1], route: [a]}\n"),
            "j.yaml:3:56: 'route' must be a name");
  EXPECT_EQ(message("skelflow_edits: 1\nops:\n- {op: delete_node, at: [1, 2]}\n"),
            "j.yaml:3:25: 'at' must be [x, y, z]");
  EXPECT_EQ(message("skelflow_edits: 1\nops:\n- {op: prune, max_length: 1, radius_factor: -1}\n"),
            "j.yaml:3:3: radius_factor must be >= 0");
  EXPECT_EQ(message("skelflow_edits: 1\nops: {a: 1}\n"), "j.yaml:2:6: 'ops' must be a list");
}
