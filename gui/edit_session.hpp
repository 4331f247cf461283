#pragma once
// The model of the graph edit mode (thesis §6.1, issue 10): a GraphEditor over a copy of a graph
// output, a QUndoStack bridged to the editor's exact undo (one QUndoCommand per editor operation;
// multi-step user actions are QUndoStack macros), the current selection, the dangling-end tour and
// saving. No VTK and no window: the 3D view's EditMode drives it, tests can drive it directly.
//
// The journal (`<node>.<port>.edits.yaml` by default) is appended and fsync'd by the GraphEditor
// after every operation, undo and redo; a kill loses nothing. Opening a graph whose journal exists
// replays it (resume) or starts over, as the caller decides.
#include <QObject>
#include <QString>
#include <QStringList>
#include <QUndoStack>

#include <functional>
#include <memory>
#include <set>
#include <tuple>
#include <vector>

#include "graph/editor.hpp"
#include "graph_pick.hpp"
#include "skel/spatial_graph.hpp"

namespace skel::gui {

class PipelineDocument;

// One selected element: a node, or a vertex of an edge (which also selects the edge).
struct EditSelectionItem {
  GraphPick::Kind kind = GraphPick::Kind::None;
  int64_t node = -1, edge = -1, point = -1;
  Vec3 position{};
  bool operator==(const EditSelectionItem& o) const {
    return kind == o.kind && node == o.node && edge == o.edge && point == o.point;
  }
};

class GraphEditSession : public QObject {
  Q_OBJECT
public:
  enum class Resume { Replay, StartOver };

  // `name` is the graph's output ("node.port"); the graph is copied once.
  GraphEditSession(const QString& name, const SpatialGraph& graph, graph::EditContext context = {},
                   QObject* parent = nullptr);
  ~GraphEditSession() override;

  [[nodiscard]] const QString& name() const { return name_; }
  [[nodiscard]] const SpatialGraph& graph() const { return editor_->graph(); }
  // The graph as a DataPtr for the 3D view: aliases the editor's graph (valid until the next edit;
  // valid as long as this session lives).
  [[nodiscard]] DataPtr graph_ptr() const;
  [[nodiscard]] graph::GraphEditor& editor() { return *editor_; }
  [[nodiscard]] QUndoStack* undo_stack() { return &undo_; }
  [[nodiscard]] bool has_mask() const { return static_cast<bool>(context_.mask); }

  // Journal: number of entries already in `path` (0 if it does not exist or holds none).
  static int journal_entries(const QString& path);
  // Starts journaling to `path`. If it holds entries: Replay applies them (each reported in
  // *report, one line per entry that did not apply) and continues the file; StartOver moves it
  // to `path.<yyyyMMdd-hhmmss>.bak` and starts a new one. Throws skel::Error on I/O problems.
  void open_journal(const QString& path, Resume resume = Resume::Replay, QStringList* report = nullptr);
  [[nodiscard]] QString journal_path() const;

  // ---- selection
  [[nodiscard]] const std::vector<EditSelectionItem>& selection() const { return selection_; }
  void set_selection(std::vector<EditSelectionItem> items);
  void toggle(const EditSelectionItem& item);  // adds or removes one element
  void add_to_selection(const std::vector<EditSelectionItem>& items);
  void clear_selection();
  [[nodiscard]] static EditSelectionItem item_from_pick(const GraphPick& p);
  [[nodiscard]] std::vector<int64_t> selected_edges() const;  // distinct edges of edge-point items
  [[nodiscard]] std::vector<int64_t> selected_nodes() const;

  // ---- operations on the selection (false with message() emitted when not applicable)
  bool delete_selected();   // Delete: selected edges (one editor op), then selected nodes
  bool connect_selected();  // C: two selected elements; an edge point is split first
  bool split_selected();    // S: at the selected interior edge vertex
  bool merge_selected();    // M: at the selected degree-2 node
  // Route of new connections: "straight" or "mask" (needs a mask in the context).
  void set_route(const QString& route) { route_ = route; }
  [[nodiscard]] const QString& route() const { return route_; }

  // ---- dangling-end tour (analysis.dangling_ends on the current graph)
  void set_dangling_options(const graph::DanglingOptions& o);
  // Goes to the next end not skipped (ends with a proposed partner first, by score). Selects the end
  // node and its partner. False when no end is left.
  bool next_dangling();
  // Accept: connect the current end to its proposed partner (one undo step).
  bool accept_dangling();
  // Skip: remember the current end as skipped and go to the next one.
  bool skip_dangling();
  [[nodiscard]] const graph::DanglingEnd* current_dangling() const;
  [[nodiscard]] int dangling_remaining();  // ends not skipped, on the current graph

  // ---- saving: writes `<base>.am` and `<base>.vtp` (graph IO of modules/graph) and syncs the
  // journal header; marks the undo stack clean. Returns the written files.
  QStringList save_graph(const QString& base);

  // Adds `graph.apply_edits` after the graph's producer in `doc` (one undo macro): input graph <-
  // name(), optional mask/distance inputs, parameter journal; every consumer of name() is rewired
  // to the new node's output. Returns the new node id (the existing one if already there).
  QString add_apply_edits_node(PipelineDocument* doc, const QString& mask_port = {},
                               const QString& distance_port = {}) const;

  // Incremented by every change of the graph (edit, undo, redo).
  [[nodiscard]] uint64_t version() const { return version_; }

signals:
  void graph_changed();
  void selection_changed();
  void dangling_changed();
  void message(const QString& text, bool error);

private:
  friend class EditorCommand;
  // Runs one editor operation and pushes its bridge command. Catches skel::Error -> message().
  bool run_op(const std::function<graph::EditOp()>& op);
  void after_change();  // graph changed: bump version, drop the selection
  void refresh_dangling();

  QString name_;
  graph::EditContext context_;
  std::unique_ptr<graph::GraphEditor> editor_;
  std::shared_ptr<int> alive_ = std::make_shared<int>(0);
  QUndoStack undo_;
  std::vector<EditSelectionItem> selection_;
  QString route_ = "straight";
  uint64_t version_ = 0;
  // Tour state.
  graph::DanglingOptions dangling_options_;
  std::vector<graph::DanglingEnd> ends_;
  uint64_t ends_version_ = ~uint64_t{0};
  int current_ = -1;
  std::set<std::tuple<double, double, double>> skipped_;
};

}  // namespace skel::gui
