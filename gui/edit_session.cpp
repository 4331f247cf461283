#include "edit_session.hpp"

#include <QDateTime>
#include <QDir>
#include <QFile>
#include <QFileInfo>

#include <algorithm>
#include <cmath>

#include "graph/names.hpp"
#include "io/graph_io.hpp"
#include "pipeline_document.hpp"
#include "skel/error.hpp"

using namespace skel::io;

namespace skel::gui {

namespace {
std::string str(const QString& s) { return s.toStdString(); }
QString qstr(const std::string& s) { return QString::fromStdString(s); }
std::tuple<double, double, double> key(const Vec3& p) { return {p[0], p[1], p[2]}; }
constexpr double kExact = 1e-9;  // re-finding an element at its own position after ids shifted
}  // namespace

// One editor operation on the QUndoStack. The operation has already run when the command is pushed
// (so a refused operation never reaches the stack); the first redo() (QUndoStack::push) does nothing,
// later ones call GraphEditor::redo(), undo() calls GraphEditor::undo(). The two stacks stay in step
// because both are linear and a new operation clears both redo lists.
class EditorCommand final : public QUndoCommand {
public:
  EditorCommand(GraphEditSession* s, const QString& text, QUndoCommand* parent = nullptr)
      : QUndoCommand(text, parent), s_(s) {}
  void redo() override {
    if (first_) {
      first_ = false;
      return;
    }
    try {
      s_->editor_->redo();
    } catch (const std::exception& e) {
      emit s_->message(QString("redo failed: ") + e.what(), true);
    }
    s_->after_change();
  }
  void undo() override {
    s_->editor_->undo();
    s_->after_change();
  }

private:
  GraphEditSession* s_;
  bool first_ = true;
};

GraphEditSession::GraphEditSession(const QString& name, const SpatialGraph& graph, graph::EditContext context,
                                   QObject* parent)
    : QObject(parent), name_(name), context_(context),
      editor_(std::make_unique<graph::GraphEditor>(SpatialGraph(graph), std::move(context))) {}

GraphEditSession::~GraphEditSession() {
  // Commands refer to the editor: drop them first.
  undo_.clear();
}

DataPtr GraphEditSession::graph_ptr() const {
  return std::shared_ptr<const SpatialGraph>(alive_, &editor_->graph());
}

int GraphEditSession::journal_entries(const QString& path) {
  if (!QFileInfo::exists(path)) return 0;
  try {
    return static_cast<int>(graph::read_journal(str(path)).ops.size());
  } catch (const std::exception&) {
    return 0;
  }
}

void GraphEditSession::open_journal(const QString& path, Resume resume, QStringList* report) {
  const int entries = journal_entries(path);
  if (entries > 0 && resume == Resume::StartOver) {
    const QString bak = path + "." + QDateTime::currentDateTime().toString("yyyyMMdd-hhmmss") + ".bak";
    if (!QFile::rename(path, bak)) throw Error("cannot move the old journal " + str(path) + " to " + str(bak));
    if (report) report->append("previous journal kept as " + bak);
  } else if (entries > 0) {
    const graph::Journal j = graph::read_journal(str(path));
    if (report && !j.dropped.empty()) report->append(qstr(j.dropped));
    // Replay without journaling (the entries are in the file already); mirror the resulting undo
    // history on the QUndoStack so Ctrl+Z continues where the last session stopped.
    std::vector<QString> done, undone;
    int failed = 0;
    for (size_t i = 0; i < j.ops.size(); ++i) {
      const auto& op = j.ops[i];
      const auto r = editor_->apply(op, j.tolerance);
      if (!r.applied) {
        ++failed;
        if (report) report->append(QString("entry %1 (%2): %3").arg(i).arg(qstr(op.to_yaml()), qstr(r.message)));
        continue;
      }
      if (op.op == graph::EditKind::undo) {
        undone.push_back(done.back());
        done.pop_back();
      } else if (op.op == graph::EditKind::redo) {
        done.push_back(undone.back());
        undone.pop_back();
      } else {
        done.push_back(qstr(op.to_yaml()));
        undone.clear();
      }
    }
    for (const QString& text : done) undo_.push(new EditorCommand(this, "(resumed) " + text));
    if (report) report->prepend(QString("resumed %1 journal entries (%2 did not apply)").arg(j.ops.size()).arg(failed));
    version_++;
  }
  // Match tolerance of the entries: one voxel of the source grid (1 when the grid is unknown).
  const Grid& grid = editor_->graph().source_grid;
  double tolerance = 1.0;
  if (grid.dims[0] > 0) tolerance = std::max({grid.spacing[0], grid.spacing[1], grid.spacing[2]});
  editor_->set_journal(str(path), tolerance);
  undo_.setClean();
  after_change();
}

QString GraphEditSession::journal_path() const { return qstr(editor_->journal().string()); }

// ---------------------------------------------------------------- selection
void GraphEditSession::set_selection(std::vector<EditSelectionItem> items) {
  selection_ = std::move(items);
  emit selection_changed();
}

void GraphEditSession::toggle(const EditSelectionItem& item) {
  auto it = std::find(selection_.begin(), selection_.end(), item);
  if (it != selection_.end()) selection_.erase(it);
  else selection_.push_back(item);
  emit selection_changed();
}

void GraphEditSession::add_to_selection(const std::vector<EditSelectionItem>& items) {
  for (const auto& i : items) {
    if (std::find(selection_.begin(), selection_.end(), i) == selection_.end()) selection_.push_back(i);
  }
  emit selection_changed();
}

void GraphEditSession::clear_selection() {
  if (selection_.empty()) return;
  selection_.clear();
  emit selection_changed();
}

EditSelectionItem GraphEditSession::item_from_pick(const GraphPick& p) {
  EditSelectionItem i;
  i.kind = p.kind;
  i.node = p.node;
  i.edge = p.edge;
  i.point = p.point;
  i.position = p.position;
  return i;
}

std::vector<int64_t> GraphEditSession::selected_edges() const {
  std::vector<int64_t> r;
  for (const auto& i : selection_) {
    if (i.kind == GraphPick::Kind::EdgePoint && std::find(r.begin(), r.end(), i.edge) == r.end()) r.push_back(i.edge);
  }
  return r;
}

std::vector<int64_t> GraphEditSession::selected_nodes() const {
  std::vector<int64_t> r;
  for (const auto& i : selection_) {
    if (i.kind == GraphPick::Kind::Node && std::find(r.begin(), r.end(), i.node) == r.end()) r.push_back(i.node);
  }
  return r;
}

// ---------------------------------------------------------------- operations
bool GraphEditSession::run_op(const std::function<graph::EditOp()>& op) {
  try {
    const graph::EditOp done = op();
    undo_.push(new EditorCommand(this, qstr(done.to_yaml())));
    emit message("edit: " + qstr(done.to_yaml()), false);
    after_change();
    return true;
  } catch (const std::exception& e) {
    emit message(QString("edit refused: ") + e.what(), true);
    return false;
  }
}

void GraphEditSession::after_change() {
  ++version_;
  selection_.clear();
  emit graph_changed();
  emit selection_changed();
}

bool GraphEditSession::delete_selected() {
  const auto edges = selected_edges();
  std::vector<Vec3> nodes;
  for (int64_t n : selected_nodes()) nodes.push_back(editor_->graph().positions[n]);
  if (edges.empty() && nodes.empty()) {
    emit message("Delete: nothing selected", true);
    return false;
  }
  const bool macro = (edges.empty() ? 0u : 1u) + nodes.size() > 1;
  if (macro) undo_.beginMacro(QString("delete %1 edges, %2 nodes").arg(edges.size()).arg(nodes.size()));
  bool ok = true;
  if (!edges.empty()) ok = run_op([&] { return editor_->delete_edges(edges); });
  for (const Vec3& p : nodes) {
    if (!ok) break;
    ok = run_op([&] {
      const int64_t n = editor_->node_at(p, kExact);
      if (n < 0) throw Error("the selected node is gone");
      return editor_->delete_node(n);
    });
  }
  if (macro) undo_.endMacro();
  return ok;
}

bool GraphEditSession::connect_selected() {
  if (selection_.size() != 2) {
    emit message("Connect: select exactly two nodes or edge points (click, Ctrl+click)", true);
    return false;
  }
  EditSelectionItem a = selection_[0], b = selection_[1];
  const SpatialGraph& g = editor_->graph();
  // An edge point at a polyline end is the node there.
  auto normalise = [&](EditSelectionItem& i) {
    if (i.kind != GraphPick::Kind::EdgePoint) return;
    const auto& e = g.edges[i.edge];
    if (i.point == 0 || i.point == static_cast<int64_t>(e.points.size()) - 1) {
      i.node = i.point == 0 ? e.node0 : e.node1;
      i.kind = GraphPick::Kind::Node;
      i.position = g.positions[i.node];
    }
  };
  normalise(a);
  normalise(b);
  if (a.kind != GraphPick::Kind::Node && b.kind == GraphPick::Kind::Node) std::swap(a, b);
  const bool macro = a.kind != GraphPick::Kind::Node;
  if (macro) undo_.beginMacro("connect (split first)");
  bool ok = true;
  if (a.kind != GraphPick::Kind::Node) {
    ok = run_op([&] { return editor_->split(a.edge, a.point); });
  }
  if (ok) {
    ok = run_op([&] {
      const int64_t from = editor_->node_at(a.position, kExact);
      if (from < 0) throw Error("the first selected node is gone");
      if (b.kind == GraphPick::Kind::Node) {
        const int64_t to = editor_->node_at(b.position, kExact);
        if (to < 0) throw Error("the second selected node is gone");
        if (to == from) throw Error("cannot connect a node to itself");
        return editor_->connect(from, to, -1, -1, parse_enum<graph::Route>(str(route_), "route"));
      }
      int64_t pt = -1;
      const int64_t e = editor_->edge_at(b.position, kExact, &pt);
      if (e < 0) throw Error("the selected edge point is gone");
      return editor_->connect(from, -1, e, pt, parse_enum<graph::Route>(str(route_), "route"));
    });
  }
  if (macro) undo_.endMacro();
  return ok;
}

bool GraphEditSession::split_selected() {
  if (selection_.size() != 1 || selection_[0].kind != GraphPick::Kind::EdgePoint) {
    emit message("Split: select one point on an edge", true);
    return false;
  }
  const auto s = selection_[0];
  const auto& pts = editor_->graph().edges[s.edge].points;
  if (s.point <= 0 || s.point >= static_cast<int64_t>(pts.size()) - 1) {
    emit message("Split: pick an interior point of the edge (not its end)", true);
    return false;
  }
  return run_op([&] { return editor_->split(s.edge, s.point); });
}

bool GraphEditSession::merge_selected() {
  if (selection_.size() != 1 || selection_[0].kind != GraphPick::Kind::Node) {
    emit message("Merge: select one node of degree 2", true);
    return false;
  }
  const int64_t n = selection_[0].node;
  return run_op([&] { return editor_->merge(n); });
}

// ---------------------------------------------------------------- dangling-end tour
void GraphEditSession::set_dangling_options(const graph::DanglingOptions& o) {
  dangling_options_ = o;
  ends_version_ = ~uint64_t{0};
}

void GraphEditSession::refresh_dangling() {
  if (ends_version_ == version_) return;
  ends_ = graph::find_dangling_ends(editor_->graph(), dangling_options_);
  ends_version_ = version_;
  current_ = -1;
}

bool GraphEditSession::next_dangling() {
  refresh_dangling();
  const int n = static_cast<int>(ends_.size());
  for (int k = 1; k <= n; ++k) {
    const int i = (current_ + k + n) % n;
    if (skipped_.count(key(ends_[i].position))) continue;
    current_ = i;
    const auto& d = ends_[i];
    std::vector<EditSelectionItem> sel;
    EditSelectionItem end;
    end.kind = GraphPick::Kind::Node;
    end.node = d.node;
    end.position = d.position;
    sel.push_back(end);
    if (d.has_partner) {
      EditSelectionItem p;
      p.position = d.partner_position;
      if (d.partner_is_node) {
        p.kind = GraphPick::Kind::Node;
        p.node = d.partner_node;
      } else {
        p.kind = GraphPick::Kind::EdgePoint;
        p.edge = d.partner_edge;
        p.point = d.partner_point;
      }
      sel.push_back(p);
    }
    selection_ = std::move(sel);
    emit selection_changed();
    emit dangling_changed();
    emit message(QString("dangling end %1 of %2 at [%3, %4, %5]: %6")
                     .arg(i + 1)
                     .arg(n)
                     .arg(d.position[0])
                     .arg(d.position[1])
                     .arg(d.position[2])
                     .arg(d.has_partner ? QString("partner %1 at distance %2, angle %3°")
                                              .arg(d.partner_is_node ? "end/node" : "edge point")
                                              .arg(d.distance, 0, 'f', 2)
                                              .arg(d.angle_deg, 0, 'f', 1)
                                        : QString("no partner within reach")),
                 false);
    return true;
  }
  current_ = -1;
  emit dangling_changed();
  emit message("no dangling ends left", false);
  return false;
}

const graph::DanglingEnd* GraphEditSession::current_dangling() const {
  if (ends_version_ != version_ || current_ < 0 || current_ >= static_cast<int>(ends_.size())) return nullptr;
  return &ends_[current_];
}

int GraphEditSession::dangling_remaining() {
  refresh_dangling();
  int r = 0;
  for (const auto& d : ends_) r += skipped_.count(key(d.position)) ? 0 : 1;
  return r;
}

bool GraphEditSession::accept_dangling() {
  const graph::DanglingEnd* d = current_dangling();
  if (!d) {
    emit message("Accept: no current dangling end (press N)", true);
    return false;
  }
  if (!d->has_partner) {
    emit message("Accept: this end has no proposed partner; select a point and press C, or skip", true);
    return false;
  }
  const graph::DanglingEnd e = *d;
  const bool ok = run_op([&] {
    return editor_->connect(e.node, e.partner_is_node ? e.partner_node : -1, e.partner_edge, e.partner_point,
                            parse_enum<graph::Route>(str(route_), "route"));
  });
  emit dangling_changed();
  return ok;
}

bool GraphEditSession::skip_dangling() {
  const graph::DanglingEnd* d = current_dangling();
  if (d) skipped_.insert(key(d->position));
  return next_dangling();
}

// ---------------------------------------------------------------- saving
QStringList GraphEditSession::save_graph(const QString& base) {
  QStringList written;
  for (const char* ext : {".am", ".vtp"}) {
    const std::filesystem::path p = str(base + ext);
    write_graph(editor_->graph(), p, graph_format_from_path(p));
    written << base + ext;
  }
  if (!editor_->journal().empty() && !QFileInfo::exists(journal_path())) editor_->set_journal(editor_->journal());
  undo_.setClean();
  return written;
}

QString GraphEditSession::add_apply_edits_node(PipelineDocument* doc, const QString& mask_port,
                                               const QString& distance_port) const {
  const auto ref = parse_port_ref(str(name_));
  if (!ref || !doc->has_node(qstr(ref->node))) throw InputError("the graph " + str(name_) + " is not a node output of this pipeline");
  // The journal path relative to the pipeline's folder when it lies inside it.
  QString journal = journal_path();
  const QString base = qstr(doc->pipeline().base_dir().string());
  if (!base.isEmpty()) {
    const QString rel = QDir(base).relativeFilePath(journal);
    if (!rel.startsWith("..")) journal = rel;
  }
  for (const auto& n : doc->pipeline().nodes()) {
    if (n.module != graph::names::apply_edits) continue;
    auto in = n.inputs.find("graph");
    auto jp = n.params.find("journal");
    if (in != n.inputs.end() && in->second == *ref && jp != n.params.end() &&
        std::holds_alternative<std::string>(jp->second) && qstr(std::get<std::string>(jp->second)) == journal)
      return qstr(n.id);
  }
  // Consumers of the graph before the new node exists.
  std::vector<std::pair<std::string, std::string>> consumers;
  for (const auto& n : doc->pipeline().nodes()) {
    for (const auto& [port, from] : n.inputs) {
      if (from == *ref) consumers.emplace_back(n.id, port);
    }
  }
  QUndoStack* stack = doc->undo_stack();
  stack->beginMacro("Add " + QString(graph::names::apply_edits) + " for " + name_);
  QString error;
  const QPointF at = doc->position(qstr(ref->node)) + QPointF(40, 110);
  const QString id = doc->add_node(graph::names::apply_edits, at, &error);
  if (id.isEmpty()) {
    stack->endMacro();
    throw Error(str(error));
  }
  QStringList problems;
  auto check = [&](const QString& e) {
    if (!e.isEmpty()) problems << e;
  };
  check(doc->set_param(id, "journal", ParamValue(str(journal))));
  check(doc->connect_ports(qstr(ref->node), qstr(ref->port), id, "graph"));
  if (const auto m = parse_port_ref(str(mask_port))) check(doc->connect_ports(qstr(m->node), qstr(m->port), id, "mask"));
  if (const auto d = parse_port_ref(str(distance_port)))
    check(doc->connect_ports(qstr(d->node), qstr(d->port), id, "distance"));
  for (const auto& [node, port] : consumers) check(doc->connect_ports(id, "graph", qstr(node), qstr(port)));
  stack->endMacro();
  if (!problems.isEmpty()) throw Error("adding " + str(id) + ": " + str(problems.join("; ")));
  return id;
}

}  // namespace skel::gui
