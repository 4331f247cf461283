#pragma once
// The Qt-side document: the engine's Pipeline (single source of truth for nodes, parameters and
// connections), node positions for the editor, the file path and a QUndoStack. Every edit goes
// through one of the methods below and becomes one QUndoCommand, so the node editor and the
// properties panel are views over this object and the same operations are testable without a window.
#include <QMap>
#include <QObject>
#include <QPointF>
#include <QString>
#include <QStringList>
#include <QUndoStack>

#include <algorithm>

#include "skel/pipeline.hpp"

namespace skel::gui {

// Everything an undoable edit may change.
struct DocState {
  Pipeline pipeline;
  QMap<QString, QPointF> positions;  // node id -> scene position of the node's top-left corner
};

class PipelineDocument : public QObject {
  Q_OBJECT
public:
  explicit PipelineDocument(QObject* parent = nullptr, const Registry& registry = Registry::instance());

  [[nodiscard]] const Pipeline& pipeline() const { return state_.pipeline; }
  [[nodiscard]] const Registry& registry() const { return registry_; }
  [[nodiscard]] QUndoStack* undo_stack() { return &undo_; }
  [[nodiscard]] QStringList node_ids() const;
  [[nodiscard]] bool has_node(const QString& id) const;
  [[nodiscard]] const ModuleSpec* spec(const QString& node) const;  // nullptr for unknown modules
  [[nodiscard]] QPointF position(const QString& node) const;
  [[nodiscard]] const QMap<QString, QPointF>& positions() const { return state_.positions; }

  // Nodes without a stored position are laid out by their depth in the graph, one column per depth;
  // a pipeline deeper than `columns` wraps into bands of that many columns, one below the other and
  // read like lines of text, so a long chain becomes rows that fit the editor at a legible zoom
  // (MainWindow sets it from the node editor's width before opening a file). At least 2.
  void set_layout_columns(int columns) { layout_columns_ = std::max(columns, 2); }
  [[nodiscard]] int layout_columns() const { return layout_columns_; }
  // Size of a node in the editor (scene units): a header, one row per input/output pair, a footer.
  static constexpr double kNodeWidth = 180, kNodeHeader = 38, kNodeRow = 20, kNodeFooter = 24;
  [[nodiscard]] static double node_height(const ModuleSpec* spec);
  // Grid of the automatic layout: columns this far apart, nodes in a column this far apart vertically.
  static constexpr double kLayoutColumnStep = 220, kLayoutGap = 30, kLayoutBandGap = 40;

  // --- files (not undoable; they reset the undo stack) ---
  void clear();                                  // new, empty document
  void load(const QString& path);                // throws skel::Error (InputError with line:column)
  // Loads YAML text; `file_name` is used in messages, relative paths resolve against `base_dir`.
  void load_text(const QString& yaml, const QString& file_name, const QString& base_dir);
  void save(const QString& path);                // atomic; node positions go into the `gui:` section
  [[nodiscard]] QString to_yaml() const;         // the YAML save() would write
  [[nodiscard]] const QString& file_path() const { return file_path_; }  // empty if never saved
  [[nodiscard]] bool is_modified() const { return !undo_.isClean(); }

  // --- edits (each one undoable command; on refusal nothing changes and the reason is returned) ---
  // Adds a node of `module` at `pos`; returns its id (e.g. "threshold2") or empty with *error set.
  QString add_node(const QString& module, QPointF pos, QString* error = nullptr);
  void remove_nodes(const QStringList& ids);     // with every connection from or to them
  // Moves nodes to new positions (one command, e.g. at the end of a drag).
  void move_nodes(const QMap<QString, QPointF>& new_positions);
  // Connects to_node.to_port <- from_node.from_port, replacing an existing connection of that
  // input. Returns the engine's refusal reason (type mismatch, cycle, unknown port) or empty.
  QString connect_ports(const QString& from_node, const QString& from_port, const QString& to_node,
                        const QString& to_port);
  void disconnect_port(const QString& to_node, const QString& to_port);
  // Sets a parameter after coercion and the spec's check (type, range, choices, length).
  QString set_param(const QString& node, const QString& param, const ParamValue& value);
  void reset_param(const QString& node, const QString& param);
  QString rename_node(const QString& id, const QString& new_id);

  // Clipboard text (a small pipeline YAML with relative positions) for the given nodes and the
  // connections among them.
  [[nodiscard]] QString copy_nodes(const QStringList& ids) const;
  // Pastes clipboard text as new nodes (fresh ids, internal connections kept) shifted by `offset`.
  // Returns the new ids; empty with *error set if the text is not a pipeline snippet.
  QStringList paste(const QString& text, QPointF offset, QString* error = nullptr);

  // Used by the undo commands.
  enum class Change { Structure, Param, Move };
  void apply_state(const DocState& state, Change change, const QString& node);

signals:
  void graph_changed();                  // nodes or connections changed
  void nodes_moved(const QStringList& ids);
  void param_changed(const QString& node);
  void document_reset();                 // loaded, cleared
  void file_path_changed(const QString& path);
  void modified_changed(bool modified);

private:
  void push(const QString& text, DocState after, Change change, const QString& node = {});
  void set_positions_from_gui_section();
  [[nodiscard]] std::string gui_section() const;

  const Registry& registry_;
  DocState state_;
  QUndoStack undo_;
  QString file_path_;
  int layout_columns_ = 4;
};

// Port colour key shared by the editor and tests: the first type id of a port.
QString port_type_label(const PortSpec& port);

}  // namespace skel::gui
