#pragma once
// Node editor: a QGraphicsScene that mirrors the PipelineDocument (it owns no graph of its own) and a
// QGraphicsView with zoom, pan, rubber-band selection and drops from the module palette. Edits made
// with the mouse are sent to the document as commands; the scene redraws from the document's
// signals, so undo/redo and file loads need no special handling here.
#include <QGraphicsItem>
#include <QGraphicsPathItem>
#include <QGraphicsScene>
#include <QGraphicsView>
#include <QHash>
#include <QPointer>

#include "pipeline_document.hpp"
#include "run_controller.hpp"

namespace skel::gui {

inline constexpr const char* kModuleMime = "application/x-skelflow-module";

// Colour of a port type ("volume.u8", "table", ...), stable across runs.
QColor port_color(const QString& type_label);
// Colour of a node state (idle, stale, running, done, error, ...).
QColor state_color(NodeState s);

class NodeScene;

class PortItem final : public QGraphicsItem {
public:
  PortItem(QGraphicsItem* parent, QString node, const PortSpec& spec, bool output);
  [[nodiscard]] QRectF boundingRect() const override;
  void paint(QPainter* p, const QStyleOptionGraphicsItem* o, QWidget* w) override;
  [[nodiscard]] const QString& node() const { return node_; }
  [[nodiscard]] const QString& port() const { return port_; }
  [[nodiscard]] bool is_output() const { return output_; }
  [[nodiscard]] QColor color() const { return color_; }
  [[nodiscard]] QPointF anchor() const { return mapToScene(QPointF(0, 0)); }  // edge end, scene coords
  enum { Type = UserType + 2 };
  [[nodiscard]] int type() const override { return Type; }

private:
  QString node_, port_;
  bool output_;
  QColor color_;
};

class NodeItem final : public QGraphicsItem {
public:
  NodeItem(NodeScene* scene, const QString& id, const QString& module, const ModuleSpec* spec);
  [[nodiscard]] QRectF boundingRect() const override;
  void paint(QPainter* p, const QStyleOptionGraphicsItem* o, QWidget* w) override;
  [[nodiscard]] const QString& id() const { return id_; }
  [[nodiscard]] const QString& module() const { return module_; }
  [[nodiscard]] PortItem* input(const QString& port) const { return inputs_.value(port); }
  [[nodiscard]] PortItem* output(const QString& port) const { return outputs_.value(port); }
  void set_status(const NodeStatus& s);
  [[nodiscard]] const NodeStatus& status() const { return status_; }
  // The module runs block by block under a memory budget (ModuleSpec::blockwise): a "blocks" badge
  // in the header and a line in the tooltip, as `skelflow validate` lists such stages.
  [[nodiscard]] bool blockwise() const { return blockwise_; }
  enum { Type = UserType + 1 };
  [[nodiscard]] int type() const override { return Type; }

protected:
  QVariant itemChange(GraphicsItemChange change, const QVariant& value) override;

private:
  [[nodiscard]] QString blockwise_tip() const;
  NodeScene* scene_;
  QString id_, module_;
  bool known_;
  bool blockwise_ = false;
  qreal height_;
  QHash<QString, PortItem*> inputs_, outputs_;
  NodeStatus status_;
};

class EdgeItem final : public QGraphicsPathItem {
public:
  EdgeItem(QString to_node, QString to_port, QColor color);
  void set_ends(QPointF from, QPointF to);
  [[nodiscard]] const QString& to_node() const { return to_node_; }
  [[nodiscard]] const QString& to_port() const { return to_port_; }
  void paint(QPainter* p, const QStyleOptionGraphicsItem* o, QWidget* w) override;
  enum { Type = UserType + 3 };
  [[nodiscard]] int type() const override { return Type; }

private:
  QString to_node_, to_port_;
  QColor color_;
};

class NodeScene final : public QGraphicsScene {
  Q_OBJECT
public:
  NodeScene(PipelineDocument* doc, RunController* run, QObject* parent = nullptr);
  ~NodeScene() override;
  [[nodiscard]] PipelineDocument* document() const { return doc_; }
  [[nodiscard]] NodeItem* node_item(const QString& id) const { return nodes_.value(id); }
  [[nodiscard]] QStringList selected_node_ids() const;
  void select_nodes(const QStringList& ids);
  // Deletes the selected nodes and connections (one undoable command each).
  void delete_selection();
  void node_moved(const QString& id);  // a node item moved: redraw its edges

signals:
  void output_port_clicked(const QString& node, const QString& port);
  void message(const QString& text);  // e.g. the engine's reason for refusing a connection
  void node_selection_changed(const QStringList& ids);

public slots:
  void sync();              // rebuild items from the document (structure changed)
  void sync_positions();    // positions changed (move, undo of a move)
  void update_status(const QString& node);

protected:
  void mousePressEvent(QGraphicsSceneMouseEvent* e) override;
  void mouseMoveEvent(QGraphicsSceneMouseEvent* e) override;
  void mouseReleaseEvent(QGraphicsSceneMouseEvent* e) override;

private:
  void rebuild_edges();
  void show_refusal(QPointF at, const QString& text);
  PortItem* port_at(QPointF scene_pos) const;

  PipelineDocument* doc_;
  QPointer<RunController> run_;
  QHash<QString, NodeItem*> nodes_;
  QList<EdgeItem*> edges_;
  bool syncing_ = false;
  // Connection drag in progress.
  PortItem* drag_port_ = nullptr;
  QGraphicsPathItem* drag_line_ = nullptr;
  QPointF press_pos_;
};

class NodeView final : public QGraphicsView {
  Q_OBJECT
public:
  explicit NodeView(NodeScene* scene, QWidget* parent = nullptr);
  // The smallest zoom fit_all() uses: node names (10 pt) stay at least 9 pt on screen.
  static constexpr double kLegibleZoom = 0.9;
  // Shows the whole pipeline, at most 1:1 and at least kLegibleZoom: a pipeline too large for that
  // is fitted to the view's width when it can be, and shown from its start (top left), the rest a
  // scroll away.
  void fit_all();
  // How many layout columns (PipelineDocument::set_layout_columns) fit a view `width` pixels wide at
  // kLegibleZoom.
  [[nodiscard]] static int legible_columns(int width);
  void zoom(double factor);
  // Scene position of the visible centre (where pasted or double-clicked modules go).
  [[nodiscard]] QPointF visible_center() const;

protected:
  void wheelEvent(QWheelEvent* e) override;
  void mousePressEvent(QMouseEvent* e) override;
  void mouseMoveEvent(QMouseEvent* e) override;
  void mouseReleaseEvent(QMouseEvent* e) override;
  void dragEnterEvent(QDragEnterEvent* e) override;
  void dragMoveEvent(QDragMoveEvent* e) override;
  void dropEvent(QDropEvent* e) override;
  void drawBackground(QPainter* p, const QRectF& rect) override;

private:
  NodeScene* scene_;
  bool panning_ = false;
  QPoint pan_last_;
};

}  // namespace skel::gui
