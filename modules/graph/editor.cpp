#include "graph/editor.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <map>
#include <numbers>
#include <numeric>
#include <optional>
#include <queue>
#include <sstream>

#include <nanoflann.hpp>
#include <yaml-cpp/yaml.h>

#include "graph/graph_ops.hpp"
#include "skel/error.hpp"
#include "skel/text.hpp"
#include "skel/union_find.hpp"

namespace skel::graph {

namespace {

double dist(const Vec3& a, const Vec3& b) {
  const double dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

// Squared distance from p to the segment [a, b].
double seg_dist2(const Vec3& p, const Vec3& a, const Vec3& b) {
  const double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double ap[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
  const double l2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
  double t = l2 > 0 ? (ab[0] * ap[0] + ab[1] * ap[1] + ab[2] * ap[2]) / l2 : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  const double d[3] = {ap[0] - t * ab[0], ap[1] - t * ab[1], ap[2] - t * ab[2]};
  return d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
}

double polyline_length(const std::vector<Vec3>& pts) {
  double l = 0;
  for (size_t i = 1; i < pts.size(); ++i) l += dist(pts[i - 1], pts[i]);
  return l;
}

// Shortest text that reads back as exactly the same double: a journal replays to the identical graph
// (move_node's target, set's value), 9 digits would move a node by up to 1e-7 relative.
std::string fmt(double d) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, d);
  return std::string(buf, r.ptr);
}
std::string fmt(const Vec3& v) { return "[" + fmt(v[0]) + ", " + fmt(v[1]) + ", " + fmt(v[2]) + "]"; }

// ---- whole-element records for exact undo of removals
struct EdgeRecord {
  GraphEdge edge;
  std::map<std::string, float> attrs;
  std::map<std::string, int32_t> labels;
  std::map<std::string, std::vector<float>> points;
};
struct NodeRecord {
  Vec3 position{};
  std::map<std::string, float> attrs;
  std::map<std::string, int32_t> labels;
};

EdgeRecord extract_edge(const SpatialGraph& g, int64_t e) {
  EdgeRecord r;
  r.edge = g.edges[e];
  for (const auto& [n, v] : g.edge_attributes) r.attrs[n] = v[e];
  for (const auto& [n, v] : g.edge_labels) r.labels[n] = v[e];
  for (const auto& [n, v] : g.point_attributes) r.points[n] = v[e];
  return r;
}
void append_edge(SpatialGraph& g, const EdgeRecord& r) {
  g.edges.push_back(r.edge);
  for (auto& [n, v] : g.edge_attributes) v.push_back(r.attrs.count(n) ? r.attrs.at(n) : 0.0f);
  for (auto& [n, v] : g.edge_labels) v.push_back(r.labels.count(n) ? r.labels.at(n) : 0);
  for (auto& [n, v] : g.point_attributes)
    v.push_back(r.points.count(n) ? r.points.at(n) : std::vector<float>(r.edge.points.size(), 0.0f));
}
void pop_edge(SpatialGraph& g) {
  g.edges.pop_back();
  for (auto& [n, v] : g.edge_attributes) v.pop_back();
  for (auto& [n, v] : g.edge_labels) v.pop_back();
  for (auto& [n, v] : g.point_attributes) v.pop_back();
}
void swap_edges(SpatialGraph& g, int64_t a, int64_t b) {
  if (a == b) return;
  std::swap(g.edges[a], g.edges[b]);
  for (auto& [n, v] : g.edge_attributes) std::swap(v[a], v[b]);
  for (auto& [n, v] : g.edge_labels) std::swap(v[a], v[b]);
  for (auto& [n, v] : g.point_attributes) std::swap(v[a], v[b]);
}
NodeRecord extract_node(const SpatialGraph& g, int64_t n) {
  NodeRecord r;
  r.position = g.positions[n];
  for (const auto& [k, v] : g.node_attributes) r.attrs[k] = v[n];
  for (const auto& [k, v] : g.node_labels) r.labels[k] = v[n];
  return r;
}
void append_node(SpatialGraph& g, const NodeRecord& r) {
  g.positions.push_back(r.position);
  for (auto& [k, v] : g.node_attributes) v.push_back(r.attrs.count(k) ? r.attrs.at(k) : 0.0f);
  for (auto& [k, v] : g.node_labels) v.push_back(r.labels.count(k) ? r.labels.at(k) : 0);
}
void pop_node(SpatialGraph& g) {
  g.positions.pop_back();
  for (auto& [k, v] : g.node_attributes) v.pop_back();
  for (auto& [k, v] : g.node_labels) v.pop_back();
}
// Swaps node ids a and b everywhere, including the edges' references. O(E).
void swap_nodes(SpatialGraph& g, int64_t a, int64_t b) {
  if (a == b) return;
  std::swap(g.positions[a], g.positions[b]);
  for (auto& [k, v] : g.node_attributes) std::swap(v[a], v[b]);
  for (auto& [k, v] : g.node_labels) std::swap(v[a], v[b]);
  for (auto& e : g.edges) {
    if (e.node0 == a) e.node0 = b;
    else if (e.node0 == b) e.node0 = a;
    if (e.node1 == a) e.node1 = b;
    else if (e.node1 == b) e.node1 = a;
  }
}

std::vector<int64_t> incident_edges(const SpatialGraph& g, int64_t n) {
  std::vector<int64_t> r;
  for (int64_t e = 0; e < g.edge_count(); ++e) {
    if (g.edges[e].node0 == n) r.push_back(e);
    if (g.edges[e].node1 == n) r.push_back(e);  // a loop appears twice
  }
  return r;
}

// Value of point attribute `values` at node n (from any incident edge's end), or nullopt.
std::optional<float> value_at_node(const SpatialGraph& g, const std::vector<std::vector<float>>& values, int64_t n,
                                   int64_t skip_edge) {
  for (int64_t e = 0; e < g.edge_count(); ++e) {
    if (e == skip_edge) continue;
    if (g.edges[e].node0 == n && !values[e].empty()) return values[e].front();
    if (g.edges[e].node1 == n && !values[e].empty()) return values[e].back();
  }
  return std::nullopt;
}

// ---- k-d tree over polyline points (nanoflann)
struct PointCloud {
  std::vector<Vec3> pts;
  std::vector<std::pair<int64_t, int64_t>> where;  // (edge, point index)
  [[nodiscard]] size_t kdtree_get_point_count() const { return pts.size(); }
  [[nodiscard]] double kdtree_get_pt(size_t i, size_t d) const { return pts[i][d]; }
  template <class B>
  bool kdtree_get_bbox(B&) const { return false; }
};
using KdTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, PointCloud>, PointCloud, 3, size_t>;

}  // namespace

// ---------------------------------------------------------------- EditOp / journal
std::string EditOp::to_yaml() const {
  std::string s = std::string("{op: ") + enum_name(op);
  if (op == EditKind::delete_edge && at.size() > 1) {
    s += ", at: [";
    for (size_t i = 0; i < at.size(); ++i) s += (i ? ", " : "") + fmt(at[i]);
    s += "]";
  } else if (!at.empty()) {
    s += ", at: " + fmt(at.front());
  }
  if (from) s += ", from: " + fmt(*from);
  if (to) s += ", to: " + fmt(*to);
  if (op == EditKind::connect || op == EditKind::bridge_gaps) s += std::string(", route: ") + enum_name(route);
  if (op == EditKind::set) s += std::string(", level: ") + enum_name(level) + ", attribute: " + attribute + ", value: " + fmt(value);
  if (op == EditKind::prune || op == EditKind::delete_components) s += ", max_length: " + fmt(length);
  if (op == EditKind::prune && radius_factor > 0) s += ", radius_factor: " + fmt(radius_factor);
  if (op == EditKind::bridge_gaps) s += ", max_distance: " + fmt(length);
  return s + "}";
}

namespace {

// The whole file as text; nullopt when it cannot be opened.
std::optional<std::string> file_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

Journal parse_whole_journal(const std::string& text, const std::string& name) {
  YAML::Node root;
  auto where = [&](const YAML::Node& n) {
    return name + ":" + std::to_string(n.Mark().line + 1) + ":" + std::to_string(n.Mark().column + 1);
  };
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw InputError(name + ":" + std::to_string(e.mark.line + 1) + ":" + std::to_string(e.mark.column + 1) +
                     ": YAML syntax error: " + e.msg);
  }
  if (!root.IsMap() || !root["skelflow_edits"])
    throw InputError(name + ": not an edit journal (expected 'skelflow_edits: 1' and 'ops:')");
  if (!root["skelflow_edits"].IsScalar() || root["skelflow_edits"].Scalar() != "1")
    throw InputError(where(root["skelflow_edits"]) + ": unsupported journal version" +
                     (root["skelflow_edits"].IsScalar() ? " '" + root["skelflow_edits"].Scalar() + "'" : std::string()) +
                     " (this Skelflow reads version 1)");
  Journal j;
  if (const YAML::Node t = root["tolerance"]) {
    try {
      j.tolerance = t.as<double>();
    } catch (const YAML::Exception&) {
      throw InputError(where(t) + ": 'tolerance' must be a number" +
                       (t.IsScalar() ? ", got '" + t.Scalar() + "'" : std::string()));
    }
  }
  const YAML::Node ops = root["ops"];
  // `ops:` with nothing after it is a journal whose session ended (or was killed) before its first
  // operation: an empty list, not an error.
  if (!ops || ops.IsNull()) return j;
  if (!ops.IsSequence()) throw InputError(where(ops) + ": 'ops' must be a list");
  auto vec = [&](const YAML::Node& n, const std::string& key) {
    if (!n.IsSequence() || n.size() != 3) throw InputError(where(n) + ": '" + key + "' must be [x, y, z]");
    try {
      return Vec3{n[0].as<double>(), n[1].as<double>(), n[2].as<double>()};
    } catch (const YAML::Exception&) {
      throw InputError(where(n) + ": '" + key + "' must be three numbers");
    }
  };
  for (const auto& n : ops) {
    if (!n.IsMap() || !n["op"]) throw InputError(where(n) + ": each entry needs 'op'");
    EditOp o;
    if (!n["op"].IsScalar()) throw InputError(where(n["op"]) + ": 'op' must be a name");
    const std::string op_name = n["op"].Scalar();
    bool known = false;
    for (const auto& k : enum_names(EditKind{}))
      if (op_name == k.name) {
        o.op = k.value;
        known = true;
      }
    if (!known) {
      std::string list;
      for (const auto& k : enum_choices<EditKind>()) {
        if (!list.empty()) list += ", ";
        list += k;
      }
      throw InputError(where(n["op"]) + ": unknown op '" + op_name + "' (expected one of " + list + ")");
    }
    // Values by key, with messages naming the key and the entry's line.
    auto number = [&](const char* key) {
      const YAML::Node v = n[key];
      try {
        return v.as<double>();
      } catch (const YAML::Exception&) {
        throw InputError(where(v) + ": '" + key + "' must be a number" +
                         (v.IsScalar() ? ", got '" + v.Scalar() + "'" : std::string()));
      }
    };
    auto name = [&](const char* key) {
      const YAML::Node v = n[key];
      if (!v.IsScalar()) throw InputError(where(v) + ": '" + key + "' must be a name");
      return v.Scalar();
    };
    if (const auto a = n["at"]) {
      if (a.IsSequence() && a.size() > 0 && a[0].IsSequence()) {
        for (const auto& p : a) o.at.push_back(vec(p, "at"));
      } else {
        o.at.push_back(vec(a, "at"));
      }
    }
    if (n["from"]) o.from = vec(n["from"], "from");
    if (n["to"]) o.to = vec(n["to"], "to");
    if (n["route"]) o.route = parse_enum<Route>(name("route"), where(n["route"]) + ": route");
    if (n["level"]) o.level = parse_enum<Level>(name("level"), where(n["level"]) + ": level");
    if (n["attribute"]) o.attribute = name("attribute");
    if (n["value"]) o.value = number("value");
    if (n["max_length"]) o.length = number("max_length");
    if (n["radius_factor"]) o.radius_factor = number("radius_factor");
    if (n["max_distance"]) o.length = number("max_distance");
    auto need = [&](bool ok, const char* what) {
      if (!ok) throw InputError(where(n) + ": op " + op_name + " needs " + what);
    };
    if (o.op == EditKind::delete_edge || o.op == EditKind::delete_node || o.op == EditKind::split || o.op == EditKind::merge || o.op == EditKind::set)
      need(!o.at.empty(), "'at'");
    if (o.op == EditKind::connect || o.op == EditKind::move_node) need(o.from && o.to, "'from' and 'to'");
    if (o.op == EditKind::set) need(!o.attribute.empty(), "'attribute'");
    if (o.op == EditKind::prune || o.op == EditKind::delete_components) need(n["max_length"].IsDefined(), "'max_length'");
    if (!(o.radius_factor >= 0)) throw InputError(where(n) + ": radius_factor must be >= 0");
    if (o.op == EditKind::bridge_gaps) need(n["max_distance"].IsDefined(), "'max_distance'");
    j.ops.push_back(std::move(o));
  }
  return j;
}

}  // namespace

// The editor appends each entry as one whole line with one write(); a SIGKILL can still cut that
// write short (Linux stops a write to a regular file between pages when a fatal signal is pending),
// leaving a last line without its newline. Such a journal reads as the entries before it, and the
// cut line is reported in `dropped`. A last line without a newline that parses (a hand-written
// journal, or a write cut just before its newline) is kept.
Journal parse_journal(const std::string& text, const std::string& name) {
  const size_t cut = text.empty() || text.back() == '\n' ? std::string::npos : text.rfind('\n');
  if (cut == std::string::npos) return parse_whole_journal(text, name);
  try {
    return parse_whole_journal(text, name);
  } catch (const InputError&) {
    // Broken before its last line too: that earlier error propagates (the YAML parser would otherwise
    // report the cut line's syntax first and hide it).
    Journal j = parse_whole_journal(text.substr(0, cut + 1), name);
    const auto line = static_cast<size_t>(std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(cut), '\n')) + 2;
    j.dropped = name + ":" + std::to_string(line) + ": the last line is incomplete (no newline; an append cut short, e.g. by a kill) and was not replayed: '" +
                text.substr(cut + 1, 80) + (text.size() - cut - 1 > 80 ? "...'" : "'");
    return j;
  }
}

Journal read_journal(const std::filesystem::path& path) {
  const std::optional<std::string> text = file_text(path);
  if (!text) throw InputError(path.string() + ": edit journal not found");
  return parse_journal(*text, path.string());
}

// ---------------------------------------------------------------- dangling ends
std::vector<DanglingEnd> find_dangling_ends(const SpatialGraph& g, const DanglingOptions& o) {
  const auto deg = g.degrees();
  PointCloud cloud;
  for (int64_t e = 0; e < g.edge_count(); ++e)
    for (int64_t i = 0; i < static_cast<int64_t>(g.edges[e].points.size()); ++i) {
      cloud.pts.push_back(g.edges[e].points[i]);
      cloud.where.emplace_back(e, i);
    }
  std::vector<DanglingEnd> out;
  if (cloud.pts.empty()) return out;
  KdTree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(16));
  tree.buildIndex();
  const double cos_max = std::cos(o.max_angle_deg * std::numbers::pi / 180.0);
  std::vector<std::pair<size_t, double>> hits;
  for (int64_t e = 0; e < g.edge_count(); ++e) {
    const auto& ed = g.edges[e];
    for (int side = 0; side < 2; ++side) {
      const int64_t n = side == 0 ? ed.node0 : ed.node1;
      if (deg[n] != 1) continue;
      DanglingEnd d;
      d.node = n;
      d.position = g.positions[n];
      // Direction: from a point `direction_length` back along the polyline to the end.
      std::vector<Vec3> pts = ed.points;
      if (side == 0) std::reverse(pts.begin(), pts.end());  // now pts.back() is the end
      double acc = 0;
      Vec3 back = pts.front();
      for (int64_t i = static_cast<int64_t>(pts.size()) - 1; i > 0; --i) {
        acc += dist(pts[i], pts[i - 1]);
        back = pts[i - 1];
        if (acc >= o.direction_length) break;
      }
      Vec3 dir{d.position[0] - back[0], d.position[1] - back[1], d.position[2] - back[2]};
      const double dl = std::sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
      if (dl > 0) dir = {dir[0] / dl, dir[1] / dl, dir[2] / dl};
      d.direction = dir;
      hits.clear();
      tree.radiusSearch(d.position.data(), o.max_distance * o.max_distance, hits, nanoflann::SearchParams(32, 0, false));
      double best = std::numeric_limits<double>::infinity();
      for (const auto& [idx, d2] : hits) {
        const auto [ce, ci] = cloud.where[idx];
        if (ce == e) continue;
        const Vec3& c = cloud.pts[idx];
        const double len = std::sqrt(d2);
        if (len <= 0) continue;
        const Vec3 v{(c[0] - d.position[0]) / len, (c[1] - d.position[1]) / len, (c[2] - d.position[2]) / len};
        const double cs = dl > 0 ? v[0] * dir[0] + v[1] * dir[1] + v[2] * dir[2] : 1.0;
        if (cs < cos_max) continue;
        const bool is_end_vertex = ci == 0 || ci == static_cast<int64_t>(g.edges[ce].points.size()) - 1;
        const int64_t pn = is_end_vertex ? (ci == 0 ? g.edges[ce].node0 : g.edges[ce].node1) : -1;
        if (pn == n) continue;
        double score = len * (1.0 + (1.0 - cs));
        if (pn >= 0 && deg[pn] == 1) score *= 0.8;  // two ends facing each other: the typical gap
        const bool better = score < best ||
                            (score == best && (ce < d.partner_edge || (ce == d.partner_edge && ci < d.partner_point)));
        if (!better) continue;
        best = score;
        d.has_partner = true;
        d.partner_is_node = pn >= 0;
        d.partner_node = pn;
        d.partner_edge = ce;
        d.partner_point = ci;
        d.partner_position = c;
        d.distance = len;
        d.angle_deg = std::acos(std::clamp(cs, -1.0, 1.0)) * 180.0 / std::numbers::pi;
        d.score = score;
      }
      out.push_back(d);
    }
  }
  std::stable_sort(out.begin(), out.end(), [](const DanglingEnd& a, const DanglingEnd& b) {
    if (a.has_partner != b.has_partner) return a.has_partner;
    if (a.score != b.score) return a.score < b.score;
    return a.node < b.node;
  });
  return out;
}

// ---------------------------------------------------------------- GraphEditor
struct GraphEditor::Step {
  EditOp op;
  std::vector<Undo> inverse;
  std::function<void()> redo;
};

GraphEditor::GraphEditor(SpatialGraph graph, EditContext context)
    : graph_(std::move(graph)), context_(std::move(context)) {
  // Headroom for added nodes and edges: without it the first edit that outgrows a vector of a
  // 10⁶-edge graph reallocates it (and every attribute column) inside one interactive operation.
  auto grow = [](auto& v) { v.reserve(v.size() + v.size() / 4 + 1024); };
  grow(graph_.positions);
  grow(graph_.edges);
  for (auto& [name, v] : graph_.node_attributes) grow(v);
  for (auto& [name, v] : graph_.node_labels) grow(v);
  for (auto& [name, v] : graph_.edge_attributes) grow(v);
  for (auto& [name, v] : graph_.edge_labels) grow(v);
  for (auto& [name, v] : graph_.point_attributes) grow(v);
}
GraphEditor::~GraphEditor() = default;

void GraphEditor::set_journal(const std::filesystem::path& path, double tolerance) {
  journal_ = path;
  journal_tolerance_ = tolerance;
  std::error_code ec;
  const bool fresh = !std::filesystem::exists(path, ec) || std::filesystem::file_size(path, ec) == 0;
  if (fresh) {
    if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path(), ec);
    std::ofstream o(path, std::ios::app);
    o << "# Skelflow edit journal: replay with graph.apply_edits (docs/editing.md).\n"
      << "# Elements are addressed by physical position; one operation per line.\n"
      << "skelflow_edits: 1\ntolerance: " << fmt(tolerance) << "\nops:\n";
    if (!o.flush()) throw InputError("cannot write the edit journal " + path.string());
    return;
  }
  // Appending to an existing journal: its last line must end in a newline, or the next entry would
  // be glued to it. A line cut short by a kill (parse_journal drops it) is cut off the file; a whole
  // last entry without its newline gets one.
  const std::string text = file_text(path).value_or(std::string());
  if (text.empty() || text.back() == '\n') return;
  const Journal j = parse_journal(text, path.string());
  if (!j.dropped.empty()) {
    std::filesystem::resize_file(path, text.rfind('\n') + 1, ec);
    if (ec) throw InputError("cannot cut the incomplete last line off the edit journal " + path.string() + ": " + ec.message());
  } else {
    std::ofstream o(path, std::ios::app);
    o << "\n";
    if (!o.flush()) throw InputError("cannot write the edit journal " + path.string());
  }
}

void GraphEditor::write_journal(const EditOp& op) {
  if (journal_.empty()) return;
  const std::string line = "- " + op.to_yaml() + "\n";
  const int fd = ::open(journal_.c_str(), O_WRONLY | O_APPEND | O_CREAT, 0644);
  if (fd < 0) throw Error("cannot append to the edit journal " + journal_.string());
  const ssize_t w = ::write(fd, line.data(), line.size());
  ::fsync(fd);
  ::close(fd);
  if (w != static_cast<ssize_t>(line.size())) throw Error("cannot append to the edit journal " + journal_.string());
}

void GraphEditor::begin() {
  if (in_step_) throw Error("GraphEditor: nested edit step");
  in_step_ = true;
  log_.clear();
}

void GraphEditor::commit(EditOp op, std::function<void()> redo) {
  auto s = std::make_unique<Step>();
  s->op = op;
  s->inverse = std::move(log_);
  s->redo = std::move(redo);
  log_.clear();
  in_step_ = false;
  undo_.push_back(std::move(s));
  redo_.clear();
  write_journal(op);
}

void GraphEditor::rollback() {
  for (auto it = log_.rbegin(); it != log_.rend(); ++it) (*it)(graph_);
  log_.clear();
  in_step_ = false;
}

// One undo step: runs `run` inside begin()/commit(), rolling every partial change back if it throws;
// `run` is kept as the step's redo.
EditOp GraphEditor::perform(EditOp op, std::function<void()> run) {
  begin();
  try {
    run();
  } catch (...) {
    rollback();
    throw;
  }
  commit(op, std::move(run));
  return op;
}

bool GraphEditor::undo() {
  if (undo_.empty()) return false;
  auto s = std::move(undo_.back());
  undo_.pop_back();
  for (auto it = s->inverse.rbegin(); it != s->inverse.rend(); ++it) (*it)(graph_);
  s->inverse.clear();
  redo_.push_back(std::move(s));
  write_journal(EditOp{EditKind::undo});
  return true;
}

bool GraphEditor::redo() {
  if (redo_.empty()) return false;
  auto s = std::move(redo_.back());
  redo_.pop_back();
  begin();
  try {
    s->redo();
  } catch (...) {
    rollback();
    throw;
  }
  s->inverse = std::move(log_);
  log_.clear();
  in_step_ = false;
  undo_.push_back(std::move(s));
  write_journal(EditOp{EditKind::redo});
  return true;
}

std::string GraphEditor::undo_text() const { return undo_.empty() ? std::string() : undo_.back()->op.to_yaml(); }

// ---- primitives
int64_t GraphEditor::p_add_node(const Vec3& p) {
  const int64_t id = graph_.add_node(p);
  record([](SpatialGraph& g) { pop_node(g); });
  return id;
}

int64_t GraphEditor::p_add_edge(int64_t n0, int64_t n1, std::vector<Vec3> pts, int64_t copy_from) {
  EdgeRecord r;
  if (copy_from >= 0) {
    r = extract_edge(graph_, copy_from);
    r.points.clear();
  }
  r.edge.node0 = n0;
  r.edge.node1 = n1;
  r.edge.points = std::move(pts);
  if (r.edge.points.size() < 2) r.edge.points = {graph_.positions[n0], graph_.positions[n1]};
  r.edge.points.front() = graph_.positions[n0];
  r.edge.points.back() = graph_.positions[n1];
  append_edge(graph_, r);
  record([](SpatialGraph& g) { pop_edge(g); });
  return graph_.edge_count() - 1;
}

void GraphEditor::p_remove_edge(int64_t e) {
  EdgeRecord r = extract_edge(graph_, e);
  const int64_t last = graph_.edge_count() - 1;
  swap_edges(graph_, e, last);
  pop_edge(graph_);
  record([r = std::move(r), e](SpatialGraph& g) {
    append_edge(g, r);
    swap_edges(g, e, g.edge_count() - 1);
  });
}

void GraphEditor::p_remove_node(int64_t n) {
  NodeRecord r = extract_node(graph_, n);
  const int64_t last = graph_.node_count() - 1;
  swap_nodes(graph_, n, last);
  pop_node(graph_);
  record([r = std::move(r), n](SpatialGraph& g) {
    append_node(g, r);
    swap_nodes(g, n, g.node_count() - 1);
  });
}

void GraphEditor::p_set_node_position(int64_t n, const Vec3& p) {
  const Vec3 old = graph_.positions[n];
  graph_.positions[n] = p;
  record([n, old](SpatialGraph& g) { g.positions[n] = old; });
}

void GraphEditor::p_set_polyline(int64_t e, std::vector<Vec3> pts,
                                 std::map<std::string, std::vector<float>, std::less<>> values) {
  std::vector<Vec3> old = graph_.edges[e].points;
  std::map<std::string, std::vector<float>, std::less<>> old_values;
  for (auto& [n, v] : graph_.point_attributes) {
    old_values[n] = v[e];
    auto it = values.find(n);
    v[e] = it != values.end() ? it->second : std::vector<float>(pts.size(), 0.0f);
    v[e].resize(pts.size(), v[e].empty() ? 0.0f : v[e].back());
  }
  graph_.edges[e].points = std::move(pts);
  record([e, old = std::move(old), old_values = std::move(old_values)](SpatialGraph& g) {
    g.edges[e].points = old;
    for (auto& [n, v] : g.point_attributes) v[e] = old_values.at(n);
  });
}

void GraphEditor::p_set_value(Level level, const std::string& name, int64_t id, double value) {
  // Creates the attribute when missing (undo removes it again).
  auto restore_erase = [&](bool node_level) {
    const bool exists = node_level ? graph_.node_attributes.count(name) > 0 : graph_.edge_attributes.count(name) > 0;
    if (exists) return;
    record([name, node_level](SpatialGraph& g) {
      if (node_level) g.node_attributes.erase(g.node_attributes.find(name));
      else g.edge_attributes.erase(g.edge_attributes.find(name));
    });
  };
  if (level == Level::node) {
    if (auto it = graph_.node_labels.find(name); it != graph_.node_labels.end()) {
      const int32_t old = it->second[id];
      it->second[id] = static_cast<int32_t>(std::lround(value));
      record([name, id, old](SpatialGraph& g) { g.node_labels.find(name)->second[id] = old; });
      return;
    }
    restore_erase(true);
    auto& v = graph_.ensure_node_attribute(name);
    const float old = v[id];
    v[id] = static_cast<float>(value);
    record([name, id, old](SpatialGraph& g) { g.node_attributes.find(name)->second[id] = old; });
    return;
  }
  if (auto it = graph_.point_attributes.find(name); it != graph_.point_attributes.end()) {
    const std::vector<float> old = it->second[id];
    std::fill(it->second[id].begin(), it->second[id].end(), static_cast<float>(value));
    record([name, id, old](SpatialGraph& g) { g.point_attributes.find(name)->second[id] = old; });
    return;
  }
  if (auto it = graph_.edge_labels.find(name); it != graph_.edge_labels.end()) {
    const int32_t old = it->second[id];
    it->second[id] = static_cast<int32_t>(std::lround(value));
    record([name, id, old](SpatialGraph& g) { g.edge_labels.find(name)->second[id] = old; });
    return;
  }
  restore_erase(false);
  auto& v = graph_.ensure_edge_attribute(name);
  const float old = v[id];
  v[id] = static_cast<float>(value);
  record([name, id, old](SpatialGraph& g) { g.edge_attributes.find(name)->second[id] = old; });
}

// ---- lookups
int64_t GraphEditor::node_at(const Vec3& p, double tolerance) const {
  int64_t best = -1;
  double bd = tolerance;
  for (int64_t n = 0; n < graph_.node_count(); ++n) {
    const double d = dist(p, graph_.positions[n]);
    if (d <= bd && (best < 0 || d < bd)) {
      bd = d;
      best = n;
    }
  }
  return best;
}

int64_t GraphEditor::edge_at(const Vec3& p, double tolerance, int64_t* point) const {
  int64_t best = -1;
  double bd2 = tolerance * tolerance;
  for (int64_t e = 0; e < graph_.edge_count(); ++e) {
    const auto& pts = graph_.edges[e].points;
    for (size_t i = 1; i < pts.size(); ++i) {
      const double d2 = seg_dist2(p, pts[i - 1], pts[i]);
      if (d2 < bd2 || (best < 0 && d2 <= bd2)) {
        bd2 = d2;
        best = e;
      }
    }
  }
  if (best >= 0 && point) {
    const auto& pts = graph_.edges[best].points;
    double pd = std::numeric_limits<double>::infinity();
    for (size_t i = 0; i < pts.size(); ++i) {
      const double d = dist(p, pts[i]);
      if (d < pd) {
        pd = d;
        *point = static_cast<int64_t>(i);
      }
    }
  }
  return best;
}

Vec3 GraphEditor::edge_probe(int64_t e) const {
  const auto& pts = graph_.edges[e].points;
  if (pts.size() >= 3) return pts[pts.size() / 2];
  return Vec3{(pts[0][0] + pts[1][0]) / 2, (pts[0][1] + pts[1][1]) / 2, (pts[0][2] + pts[1][2]) / 2};
}

// ---- routing and radii
std::vector<Vec3> GraphEditor::route_path(const Vec3& a, const Vec3& b, Route route) const {
  if (route != Route::mask) return {a, b};
  if (!context_.mask) throw InputError("connect with route: mask needs the mask input");
  const VolumeU8& m = *context_.mask;
  const Grid& gr = m.grid();
  auto to_voxel = [&](const Vec3& p) {
    std::array<int64_t, 3> v{};
    for (int k = 0; k < 3; ++k)
      v[k] = std::clamp<int64_t>(std::llround((p[k] - gr.origin[k]) / gr.spacing[k]), 0, gr.dims[k] - 1);
    return v;
  };
  const auto va = to_voxel(a), vb = to_voxel(b);
  // Dijkstra over object voxels (26-neighbourhood, physical step lengths) inside the bounding box
  // of the two ends grown by half their distance (at least 5 voxels).
  std::array<int64_t, 3> lo{}, hi{};
  for (int k = 0; k < 3; ++k) {
    const int64_t margin = std::max<int64_t>(5, std::llabs(va[k] - vb[k]) / 2 + 2);
    lo[k] = std::max<int64_t>(0, std::min(va[k], vb[k]) - margin);
    hi[k] = std::min<int64_t>(gr.dims[k] - 1, std::max(va[k], vb[k]) + margin);
  }
  const int64_t bx = hi[0] - lo[0] + 1, by = hi[1] - lo[1] + 1, bz = hi[2] - lo[2] + 1;
  const int64_t nbox = bx * by * bz;
  if (nbox > 64 * 1024 * 1024) throw InputError("connect: the two points are too far apart for routing through the mask");
  auto idx = [&](int64_t x, int64_t y, int64_t z) { return (x - lo[0]) + bx * ((y - lo[1]) + by * (z - lo[2])); };
  std::vector<double> d(static_cast<size_t>(nbox), std::numeric_limits<double>::infinity());
  std::vector<int64_t> prev(static_cast<size_t>(nbox), -1);
  using QE = std::pair<double, int64_t>;
  std::priority_queue<QE, std::vector<QE>, std::greater<>> q;
  const int64_t s = idx(va[0], va[1], va[2]), t = idx(vb[0], vb[1], vb[2]);
  d[s] = 0;
  q.push({0, s});
  while (!q.empty()) {
    auto [dd, i] = q.top();
    q.pop();
    if (dd > d[i]) continue;
    if (i == t) break;
    const int64_t x = lo[0] + i % bx, y = lo[1] + (i / bx) % by, z = lo[2] + i / (bx * by);
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          if (!dx && !dy && !dz) continue;
          const int64_t X = x + dx, Y = y + dy, Z = z + dz;
          if (X < lo[0] || Y < lo[1] || Z < lo[2] || X > hi[0] || Y > hi[1] || Z > hi[2]) continue;
          const int64_t j = idx(X, Y, Z);
          if (!m(X, Y, Z) && j != t) continue;
          const double w = std::sqrt(dx * dx * gr.spacing[0] * gr.spacing[0] + dy * dy * gr.spacing[1] * gr.spacing[1] +
                                     dz * dz * gr.spacing[2] * gr.spacing[2]);
          if (dd + w < d[j]) {
            d[j] = dd + w;
            prev[j] = i;
            q.push({d[j], j});
          }
        }
  }
  if (!std::isfinite(d[t]))
    throw InputError("connect: no path through the mask between " + fmt(a) + " and " + fmt(b));
  std::vector<Vec3> path;
  for (int64_t i = t; i >= 0; i = prev[i]) {
    const int64_t x = lo[0] + i % bx, y = lo[1] + (i / bx) % by, z = lo[2] + i / (bx * by);
    path.push_back(gr.position(static_cast<double>(x), static_cast<double>(y), static_cast<double>(z)));
    if (i == s) break;
  }
  std::reverse(path.begin(), path.end());
  if (path.size() < 2) return {a, b};
  path.front() = a;
  path.back() = b;
  return path;
}

void GraphEditor::fill_new_point_radius(int64_t e) {
  // Point attributes of a new edge: radius/thickness sampled from the distance map when given,
  // otherwise interpolated between the values at its two nodes.
  const auto& ed = graph_.edges[e];
  for (auto& [name, values] : graph_.point_attributes) {
    std::vector<float> v(ed.points.size(), 0.0f);
    const bool radius_like = name == "radius" || name == "thickness";
    if (radius_like && context_.distance) {
      const VolumeF32& dm = *context_.distance;
      const Grid& gr = dm.grid();
      for (size_t i = 0; i < v.size(); ++i) {
        int64_t c[3];
        for (int k = 0; k < 3; ++k)
          c[k] = std::clamp<int64_t>(std::llround((ed.points[i][k] - gr.origin[k]) / gr.spacing[k]), 0, gr.dims[k] - 1);
        v[i] = dm(c[0], c[1], c[2]);
      }
    } else {
      const float a = value_at_node(graph_, values, ed.node0, e).value_or(0.0f);
      const float b = value_at_node(graph_, values, ed.node1, e).value_or(a);
      const double total = polyline_length(ed.points);
      double acc = 0;
      for (size_t i = 0; i < v.size(); ++i) {
        if (i > 0) acc += dist(ed.points[i - 1], ed.points[i]);
        const double f = total > 0 ? acc / total : 0.0;
        v[i] = static_cast<float>(a + (b - a) * f);
      }
    }
    const std::vector<float> old = values[e];
    values[e] = v;
    record([n = name, e, old](SpatialGraph& g) { g.point_attributes.find(n)->second[e] = old; });
  }
}

// ---- operations (internal, inside a step)
void GraphEditor::do_delete_edges(std::vector<int64_t> edges) {
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  for (int64_t e : edges)
    if (e < 0 || e >= graph_.edge_count()) throw Error("edge " + std::to_string(e) + " does not exist");
  for (auto it = edges.rbegin(); it != edges.rend(); ++it) p_remove_edge(*it);
}

int64_t GraphEditor::do_split(int64_t e, int64_t i) {
  if (e < 0 || e >= graph_.edge_count()) throw Error("edge " + std::to_string(e) + " does not exist");
  const auto pts = graph_.edges[e].points;
  const int64_t np = static_cast<int64_t>(pts.size());
  if (i <= 0 || i >= np - 1) throw Error("split: point " + std::to_string(i) + " is an end of the edge");
  const int64_t n0 = graph_.edges[e].node0, n1 = graph_.edges[e].node1;
  const int64_t m = p_add_node(pts[i]);
  std::vector<Vec3> a(pts.begin(), pts.begin() + i + 1), b(pts.begin() + i, pts.end());
  std::map<std::string, std::vector<float>, std::less<>> va, vb;
  for (const auto& [name, v] : graph_.point_attributes) {
    va[name] = std::vector<float>(v[e].begin(), v[e].begin() + i + 1);
    vb[name] = std::vector<float>(v[e].begin() + i, v[e].end());
  }
  const int64_t ea = p_add_edge(n0, m, a, e);
  p_set_polyline(ea, a, va);
  const int64_t eb = p_add_edge(m, n1, b, e);
  p_set_polyline(eb, b, vb);
  p_remove_edge(e);
  return m;
}

void GraphEditor::do_merge(int64_t n) {
  if (n < 0 || n >= graph_.node_count()) throw Error("node " + std::to_string(n) + " does not exist");
  const auto inc = incident_edges(graph_, n);
  if (inc.size() != 2 || inc[0] == inc[1])
    throw Error("merge: node " + std::to_string(n) + " has degree " + std::to_string(inc.size()) +
                " (needs two different edges)");
  const int64_t e1 = inc[0], e2 = inc[1];
  auto oriented = [&](int64_t e, bool end_at_n) {  // points (and values) so that n is last/first
    std::vector<Vec3> p = graph_.edges[e].points;
    std::map<std::string, std::vector<float>, std::less<>> v;
    for (const auto& [name, vals] : graph_.point_attributes) v[name] = vals[e];
    const bool n_is_last = graph_.edges[e].node1 == n;
    if (n_is_last != end_at_n) {
      std::reverse(p.begin(), p.end());
      for (auto& [name, vals] : v) std::reverse(vals.begin(), vals.end());
    }
    return std::make_pair(p, v);
  };
  auto [p1, v1] = oriented(e1, true);
  auto [p2, v2] = oriented(e2, false);
  const int64_t a = graph_.edges[e1].node1 == n ? graph_.edges[e1].node0 : graph_.edges[e1].node1;
  const int64_t b = graph_.edges[e2].node0 == n ? graph_.edges[e2].node1 : graph_.edges[e2].node0;
  std::vector<Vec3> pts = p1;
  pts.insert(pts.end(), p2.begin() + 1, p2.end());
  std::map<std::string, std::vector<float>, std::less<>> vals;
  for (auto& [name, x] : v1) {
    vals[name] = x;
    vals[name].insert(vals[name].end(), v2[name].begin() + 1, v2[name].end());
  }
  // Edge values: length-weighted mean of float attributes, labels of the first edge.
  const double l1 = graph_.edge_length(e1), l2 = graph_.edge_length(e2);
  const int64_t ne = p_add_edge(a, b, pts, e1);
  p_set_polyline(ne, pts, vals);
  for (auto& [name, v] : graph_.edge_attributes) {
    const double w = l1 + l2 > 0 ? (v[e1] * l1 + v[e2] * l2) / (l1 + l2) : v[e1];
    const float old = v[ne];
    v[ne] = static_cast<float>(w);
    record([nm = name, ne, old](SpatialGraph& g) { g.edge_attributes.find(nm)->second[ne] = old; });
  }
  p_remove_edge(std::max(e1, e2));
  p_remove_edge(std::min(e1, e2));
  p_remove_node(n);
}

void GraphEditor::do_connect(int64_t from, int64_t to_node, int64_t to_edge, int64_t to_point, Route route) {
  if (from < 0 || from >= graph_.node_count()) throw Error("node " + std::to_string(from) + " does not exist");
  if (to_node < 0) {
    if (to_edge < 0 || to_edge >= graph_.edge_count()) throw Error("edge " + std::to_string(to_edge) + " does not exist");
    const int64_t np = static_cast<int64_t>(graph_.edges[to_edge].points.size());
    if (to_point <= 0) to_node = graph_.edges[to_edge].node0;
    else if (to_point >= np - 1) to_node = graph_.edges[to_edge].node1;
    else to_node = do_split(to_edge, to_point);
  }
  if (to_node < 0 || to_node >= graph_.node_count()) throw Error("node " + std::to_string(to_node) + " does not exist");
  if (to_node == from) throw Error("connect: a node cannot be connected to itself");
  const auto path = route_path(graph_.positions[from], graph_.positions[to_node], route);
  const int64_t e = p_add_edge(from, to_node, path);
  fill_new_point_radius(e);
}

// ---- public operations
EditOp GraphEditor::delete_edges(std::vector<int64_t> edges) {
  EditOp op{EditKind::delete_edge};
  for (int64_t e : edges) {
    if (e < 0 || e >= graph_.edge_count()) throw Error("edge " + std::to_string(e) + " does not exist");
    op.at.push_back(edge_probe(e));
  }
  return perform(std::move(op), [this, edges] { do_delete_edges(edges); });
}

EditOp GraphEditor::delete_node(int64_t n) {
  if (n < 0 || n >= graph_.node_count()) throw Error("node " + std::to_string(n) + " does not exist");
  EditOp op{EditKind::delete_node};
  op.at.push_back(graph_.positions[n]);
  auto run = [this, n] {
    auto inc = incident_edges(graph_, n);
    do_delete_edges(inc);
    p_remove_node(n);
  };
  return perform(std::move(op), std::move(run));
}

EditOp GraphEditor::connect(int64_t from, int64_t to_node, int64_t to_edge, int64_t to_point, Route route) {
  EditOp op{EditKind::connect};
  op.route = route;
  if (from < 0 || from >= graph_.node_count()) throw Error("node " + std::to_string(from) + " does not exist");
  op.from = graph_.positions[from];
  if (to_node >= 0) {
    if (to_node >= graph_.node_count()) throw Error("node " + std::to_string(to_node) + " does not exist");
    op.to = graph_.positions[to_node];
  } else {
    if (to_edge < 0 || to_edge >= graph_.edge_count() || to_point < 0 ||
        to_point >= static_cast<int64_t>(graph_.edges[to_edge].points.size()))
      throw Error("connect: no such edge point");
    op.to = graph_.edges[to_edge].points[to_point];
  }
  auto run = [this, from, to_node, to_edge, to_point, route] { do_connect(from, to_node, to_edge, to_point, route); };
  return perform(std::move(op), std::move(run));
}

EditOp GraphEditor::split(int64_t edge, int64_t point) {
  if (edge < 0 || edge >= graph_.edge_count() || point < 0 ||
      point >= static_cast<int64_t>(graph_.edges[edge].points.size()))
    throw Error("split: no such edge point");
  EditOp op{EditKind::split};
  op.at.push_back(graph_.edges[edge].points[point]);
  auto run = [this, edge, point] { do_split(edge, point); };
  return perform(std::move(op), std::move(run));
}

EditOp GraphEditor::merge(int64_t node) {
  if (node < 0 || node >= graph_.node_count()) throw Error("node " + std::to_string(node) + " does not exist");
  EditOp op{EditKind::merge};
  op.at.push_back(graph_.positions[node]);
  auto run = [this, node] { do_merge(node); };
  return perform(std::move(op), std::move(run));
}

EditOp GraphEditor::move_node(int64_t n, const Vec3& to) {
  if (n < 0 || n >= graph_.node_count()) throw Error("node " + std::to_string(n) + " does not exist");
  EditOp op{EditKind::move_node};
  op.from = graph_.positions[n];
  op.to = to;
  auto run = [this, n, to] {
    const Vec3 from = graph_.positions[n];
    const Vec3 delta{to[0] - from[0], to[1] - from[1], to[2] - from[2]};
    std::vector<int64_t> inc = incident_edges(graph_, n);
    inc.erase(std::unique(inc.begin(), inc.end()), inc.end());
    p_set_node_position(n, to);
    for (int64_t e : inc) {
      const auto& ed = graph_.edges[e];
      std::vector<Vec3> pts = ed.points;
      const double total = polyline_length(pts);
      const size_t np = pts.size();
      // Weight 1 at the moved end, fading linearly (by arc length) to 0 at the other end; a loop
      // moves as a whole.
      std::vector<double> w0(np, 0.0), w1(np, 0.0);
      double acc = 0;
      for (size_t i = 0; i < np; ++i) {
        if (i > 0) acc += dist(pts[i - 1], pts[i]);
        const double f = total > 0 ? acc / total : static_cast<double>(i) / static_cast<double>(np - 1);
        w0[i] = 1.0 - f;
        w1[i] = f;
      }
      for (size_t i = 0; i < np; ++i) {
        double w = 0;
        if (ed.node0 == n && ed.node1 == n) w = 1.0;
        else if (ed.node0 == n) w = w0[i];
        else w = w1[i];
        for (int k = 0; k < 3; ++k) pts[i][k] += w * delta[k];
      }
      pts.front() = graph_.positions[ed.node0];
      pts.back() = graph_.positions[ed.node1];
      std::map<std::string, std::vector<float>, std::less<>> vals;
      for (const auto& [name, v] : graph_.point_attributes) vals[name] = v[e];
      p_set_polyline(e, pts, vals);
    }
  };
  return perform(std::move(op), std::move(run));
}

EditOp GraphEditor::set_attribute(Level level, const std::vector<int64_t>& ids, const std::string& name,
                                  double value) {
  if (name.empty()) throw Error("set: attribute name is empty");
  EditOp op{EditKind::set};
  op.level = level;
  op.attribute = name;
  op.value = value;
  for (int64_t id : ids) {
    const int64_t count = level == Level::node ? graph_.node_count() : graph_.edge_count();
    if (id < 0 || id >= count) throw Error(std::string(enum_name(level)) + " " + std::to_string(id) + " does not exist");
    op.at.push_back(level == Level::node ? graph_.positions[id] : edge_probe(id));
  }
  auto run = [this, level, ids, name, value] {
    for (int64_t id : ids) p_set_value(level, name, id, value);
  };
  return perform(std::move(op), std::move(run));
}

EditOp GraphEditor::prune(double max_length, double radius_factor) {
  if (!(radius_factor >= 0)) throw InputError("prune: radius_factor must be >= 0");
  if (radius_factor > 0 && !graph_.point_attributes.contains("radius"))
    throw InputError("prune: radius_factor needs the point attribute 'radius', which this graph does not have");
  EditOp op{EditKind::prune};
  op.length = max_length;
  op.radius_factor = radius_factor;
  auto run = [this, max_length, radius_factor] {
    // graph.prune's rule (find_spurs), but every spur goes, even all of a junction's, and only the
    // junctions it touched are merged; done by the undoable primitives.
    PruneOptions rule;
    rule.min_length = max_length;
    rule.radius_factor = radius_factor;
    for (;;) {
      std::vector<int64_t> spurs, ends, junctions;
      for (const Spur& s : find_spurs(graph_, graph_.degrees(), rule)) {
        spurs.push_back(s.edge);
        ends.push_back(s.tip);
        junctions.push_back(s.junction);  // merged afterwards if left with degree 2
      }
      if (spurs.empty()) break;
      do_delete_edges(spurs);
      std::sort(ends.begin(), ends.end());
      for (auto it = ends.rbegin(); it != ends.rend(); ++it) {
        // Node ids shift when a lower node is removed by swap; remove in descending order, and map
        // the junctions through the swaps.
        const int64_t last = graph_.node_count() - 1;
        p_remove_node(*it);
        for (auto& j : junctions)
          if (j == last) j = *it;
      }
      std::sort(junctions.begin(), junctions.end());
      junctions.erase(std::unique(junctions.begin(), junctions.end()), junctions.end());
      // Merge degree-2 junctions (highest id first, mapping ids through node swaps).
      for (size_t k = junctions.size(); k-- > 0;) {
        const int64_t j = junctions[k];
        const auto inc = incident_edges(graph_, j);
        const int64_t last = graph_.node_count() - 1;
        if (inc.empty()) p_remove_node(j);  // every branch of a small star was a spur
        else if (inc.size() == 2 && inc[0] != inc[1]) do_merge(j);
        else continue;
        for (size_t q = 0; q < k; ++q)
          if (junctions[q] == last) junctions[q] = j;
      }
    }
  };
  return perform(std::move(op), std::move(run));
}

EditOp GraphEditor::delete_components(double max_length) {
  EditOp op{EditKind::delete_components};
  op.length = max_length;
  auto run = [this, max_length] {
    const int64_t nn = graph_.node_count();
    UnionFind uf(nn);
    for (const auto& e : graph_.edges) uf.unite(e.node0, e.node1);
    std::vector<double> len(static_cast<size_t>(nn), 0.0);
    for (int64_t e = 0; e < graph_.edge_count(); ++e) len[uf.find(graph_.edges[e].node0)] += graph_.edge_length(e);
    std::vector<int64_t> edges, nodes;
    for (int64_t e = 0; e < graph_.edge_count(); ++e)
      if (len[uf.find(graph_.edges[e].node0)] < max_length) edges.push_back(e);
    for (int64_t n = 0; n < nn; ++n)
      if (len[uf.find(n)] < max_length) nodes.push_back(n);
    do_delete_edges(edges);
    for (auto it = nodes.rbegin(); it != nodes.rend(); ++it) p_remove_node(*it);
  };
  return perform(std::move(op), std::move(run));
}

EditOp GraphEditor::bridge_gaps(double max_distance, Route route) {
  EditOp op{EditKind::bridge_gaps};
  op.length = max_distance;
  op.route = route;
  auto run = [this, max_distance, route] {
    DanglingOptions o;
    o.max_distance = max_distance;
    const auto ends = find_dangling_ends(graph_, o);
    std::vector<Vec3> used;  // positions already connected in this batch
    auto is_used = [&](const Vec3& p) {
      return std::any_of(used.begin(), used.end(), [&](const Vec3& u) { return u == p; });
    };
    for (const auto& d : ends) {
      if (!d.has_partner) break;
      if (is_used(d.position) || (d.partner_is_node && is_used(d.partner_position))) continue;
      // Ids shift as the batch goes: find the elements again by their (unchanged) positions.
      const int64_t from = node_at(d.position, 0.0);
      if (from < 0) continue;
      int64_t to_node = -1, to_edge = -1, to_point = -1;
      if (d.partner_is_node) {
        to_node = node_at(d.partner_position, 0.0);
        if (to_node < 0) continue;
      } else {
        to_edge = edge_at(d.partner_position, 1e-9, &to_point);
        if (to_edge < 0) continue;
      }
      try {
        do_connect(from, to_node, to_edge, to_point, route);
      } catch (const InputError&) {
        continue;  // no path through the mask for this gap: leave it
      }
      used.push_back(d.position);
      used.push_back(d.partner_position);
    }
  };
  return perform(std::move(op), std::move(run));
}

ApplyResult GraphEditor::apply(const EditOp& op, double tol) {
  ApplyResult r;
  auto fail = [&](std::string m) {
    r.applied = false;
    r.message = std::move(m);
    return r;
  };
  try {
    if (op.op == EditKind::undo) {
      if (!undo()) return fail("nothing to undo");
    } else if (op.op == EditKind::redo) {
      if (!redo()) return fail("nothing to redo");
    } else if (op.op == EditKind::delete_edge) {
      std::vector<int64_t> ids;
      for (const auto& p : op.at) {
        const int64_t e = edge_at(p, tol);
        if (e < 0) return fail("no edge within " + fmt(tol) + " of " + fmt(p));
        ids.push_back(e);
      }
      delete_edges(ids);
    } else if (op.op == EditKind::delete_node || op.op == EditKind::merge) {
      const int64_t n = node_at(op.at.front(), tol);
      if (n < 0) return fail("no node within " + fmt(tol) + " of " + fmt(op.at.front()));
      if (op.op == EditKind::delete_node) delete_node(n);
      else merge(n);
    } else if (op.op == EditKind::split) {
      int64_t pt = -1;
      const int64_t e = edge_at(op.at.front(), tol, &pt);
      if (e < 0) return fail("no edge within " + fmt(tol) + " of " + fmt(op.at.front()));
      split(e, pt);
    } else if (op.op == EditKind::connect) {
      const int64_t from = node_at(*op.from, tol);
      if (from < 0) return fail("no node within " + fmt(tol) + " of " + fmt(*op.from));
      int64_t to = node_at(*op.to, tol);
      if (to >= 0) {
        connect(from, to, -1, -1, op.route);
      } else {
        int64_t pt = -1;
        const int64_t e = edge_at(*op.to, tol, &pt);
        if (e < 0) return fail("nothing within " + fmt(tol) + " of " + fmt(*op.to) + " to connect to");
        connect(from, -1, e, pt, op.route);
      }
    } else if (op.op == EditKind::move_node) {
      const int64_t n = node_at(*op.from, tol);
      if (n < 0) return fail("no node within " + fmt(tol) + " of " + fmt(*op.from));
      move_node(n, *op.to);
    } else if (op.op == EditKind::set) {
      std::vector<int64_t> ids;
      for (const auto& p : op.at) {
        const int64_t id = op.level == Level::node ? node_at(p, tol) : edge_at(p, tol);
        if (id < 0) return fail(std::string("no ") + enum_name(op.level) + " within " + fmt(tol) + " of " + fmt(p));
        ids.push_back(id);
      }
      set_attribute(op.level, ids, op.attribute, op.value);
    } else if (op.op == EditKind::prune) {
      prune(op.length, op.radius_factor);
    } else if (op.op == EditKind::delete_components) {
      delete_components(op.length);
    } else if (op.op == EditKind::bridge_gaps) {
      bridge_gaps(op.length, op.route);
    } else {
      return fail(std::string("unknown op '") + enum_name(op.op) + "'");
    }
  } catch (const Error& e) {
    return fail(e.what());
  }
  r.applied = true;
  r.message = "applied";
  return r;
}

bool same_graph(const SpatialGraph& a, const SpatialGraph& b) {
  if (a.positions != b.positions || a.edges.size() != b.edges.size()) return false;
  for (size_t e = 0; e < a.edges.size(); ++e)
    if (a.edges[e].node0 != b.edges[e].node0 || a.edges[e].node1 != b.edges[e].node1 ||
        a.edges[e].points != b.edges[e].points)
      return false;
  auto same_map = [](const auto& x, const auto& y) {
    if (x.size() != y.size()) return false;
    for (const auto& [k, v] : x) {
      auto it = y.find(k);
      if (it == y.end() || !(it->second == v)) return false;
    }
    return true;
  };
  return same_map(a.node_attributes, b.node_attributes) && same_map(a.node_labels, b.node_labels) &&
         same_map(a.edge_attributes, b.edge_attributes) && same_map(a.edge_labels, b.edge_labels) &&
         same_map(a.point_attributes, b.point_attributes);
}

}  // namespace skel::graph
