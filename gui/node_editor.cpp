#include "node_editor.hpp"

#include <QGraphicsSceneMouseEvent>
#include <QMimeData>
#include <QPainter>
#include <QScrollBar>
#include <QStyleOptionGraphicsItem>
#include <QTimer>
#include <QWheelEvent>

#include <algorithm>
#include <cmath>

namespace skel::gui {

namespace {
constexpr qreal kWidth = PipelineDocument::kNodeWidth;
constexpr qreal kHeader = PipelineDocument::kNodeHeader;
constexpr qreal kRow = PipelineDocument::kNodeRow;
constexpr qreal kFooter = PipelineDocument::kNodeFooter;
constexpr qreal kPortRadius = 6;

QString qstr(const std::string& s) { return QString::fromStdString(s); }
}  // namespace

QColor port_color(const QString& type) {
  if (type == "volume.u8") return QColor(76, 175, 80);
  if (type == "volume.f32" || type == "volume.f64") return QColor(255, 152, 0);
  if (type == "volume.u16" || type == "volume.u32" || type == "volume.i32" || type == "volume.u64" ||
      type == "volume.int") {
    return QColor(0, 150, 136);
  }
  if (type == "volume") return QColor(158, 158, 158);
  if (type == "table") return QColor(33, 150, 243);
  if (type == "graph") return QColor(156, 39, 176);
  if (type == "mesh") return QColor(233, 30, 99);
  if (type == "landmarks") return QColor(121, 85, 72);
  if (type == "transform") return QColor(96, 125, 139);
  const uint h = qHash(type);
  return QColor::fromHsv(static_cast<int>(h % 360), 160, 200);
}

QColor state_color(NodeState s) {
  switch (s) {
    case NodeState::Idle: return QColor(120, 120, 120);
    case NodeState::Stale: return QColor(230, 170, 40);
    case NodeState::Waiting: return QColor(120, 160, 210);
    case NodeState::Running: return QColor(40, 120, 230);
    case NodeState::Done: return QColor(60, 170, 80);
    case NodeState::Cached: return QColor(90, 160, 110);
    case NodeState::Error: return QColor(220, 50, 50);
    case NodeState::Cancelled: return QColor(200, 110, 40);
  }
  return Qt::gray;
}

// ---------------------------------------------------------------- PortItem

PortItem::PortItem(QGraphicsItem* parent, QString node, const PortSpec& spec, bool output)
    : QGraphicsItem(parent), node_(std::move(node)), port_(qstr(spec.name)), output_(output) {
  const QString type = port_type_label(spec);
  color_ = port_color(type);
  QString tip = QString("<b>%1</b> (%2%3)<br>%4")
                    .arg(port_, type, !output && !spec.required ? ", optional" : "", qstr(spec.doc).toHtmlEscaped());
  if (output) tip += "<br><i>click to show in the 3D view; drag to an input to connect</i>";
  setToolTip(tip);
  setAcceptHoverEvents(true);
  setCursor(Qt::CrossCursor);
}

QRectF PortItem::boundingRect() const {
  return QRectF(-kPortRadius - 2, -kPortRadius - 2, 2 * kPortRadius + 4, 2 * kPortRadius + 4);
}

void PortItem::paint(QPainter* p, const QStyleOptionGraphicsItem*, QWidget*) {
  p->setRenderHint(QPainter::Antialiasing);
  p->setPen(QPen(color_.darker(160), 1.5));
  p->setBrush(color_);
  if (output_) {
    p->drawEllipse(QPointF(0, 0), kPortRadius, kPortRadius);
  } else {
    p->drawRect(QRectF(-kPortRadius + 1, -kPortRadius + 1, 2 * kPortRadius - 2, 2 * kPortRadius - 2));
  }
}

// ---------------------------------------------------------------- NodeItem

NodeItem::NodeItem(NodeScene* scene, const QString& id, const QString& module, const ModuleSpec* spec)
    : scene_(scene), id_(id), module_(module), known_(spec != nullptr) {
  setFlags(ItemIsMovable | ItemIsSelectable | ItemSendsGeometryChanges);
  setZValue(1);
  height_ = PipelineDocument::node_height(spec);
  if (spec) {
    for (size_t i = 0; i < spec->inputs().size(); ++i) {
      auto* port = new PortItem(this, id, spec->inputs()[i], false);
      port->setPos(0, kHeader + kRow * (static_cast<qreal>(i) + 0.5));
      inputs_.insert(port->port(), port);
    }
    for (size_t i = 0; i < spec->outputs().size(); ++i) {
      auto* port = new PortItem(this, id, spec->outputs()[i], true);
      port->setPos(kWidth, kHeader + kRow * (static_cast<qreal>(i) + 0.5));
      outputs_.insert(port->port(), port);
    }
    blockwise_ = spec->block_support().blockwise;
    setToolTip(QString("<b>%1</b><br>%2").arg(module, qstr(spec->doc()).toHtmlEscaped()) + blockwise_tip());
  } else {
    setToolTip("unknown module " + module);
  }
}

QString NodeItem::blockwise_tip() const {
  return blockwise_ ? QString("<br><i>blocks: runs block by block under a memory budget (execution: {memory_budget: "
                              "2GiB} or skelflow run --memory-budget)</i>")
                    : QString();
}

QRectF NodeItem::boundingRect() const { return QRectF(-4, -4, kWidth + 8, height_ + 8); }

void NodeItem::set_status(const NodeStatus& s) {
  status_ = s;
  QString tip = "<b>" + module_ + "</b>";
  if (!s.message.empty()) tip += "<br>" + qstr(s.message).toHtmlEscaped();
  setToolTip(tip + blockwise_tip());
  update();
}

void NodeItem::paint(QPainter* p, const QStyleOptionGraphicsItem*, QWidget*) {
  p->setRenderHint(QPainter::Antialiasing);
  const QRectF body(0, 0, kWidth, height_);
  const QColor sc = state_color(status_.state);
  // Body and state-coloured frame (thicker when selected).
  p->setPen(QPen(isSelected() ? QColor(255, 255, 255) : sc, isSelected() ? 3 : 2));
  p->setBrush(QColor(48, 52, 58));
  p->drawRoundedRect(body, 6, 6);
  // Header.
  p->setPen(Qt::NoPen);
  p->setBrush(known_ ? QColor(62, 68, 78) : QColor(120, 40, 40));
  p->drawRoundedRect(QRectF(1, 1, kWidth - 2, kHeader - 2), 5, 5);
  QFont f = p->font();
  f.setBold(true);
  f.setPointSizeF(10);
  p->setFont(f);
  p->setPen(Qt::white);
  p->drawText(QRectF(8, 2, kWidth - 16, 18), Qt::AlignLeft | Qt::AlignVCenter, id_);
  f.setBold(false);
  f.setPointSizeF(8);
  p->setFont(f);
  p->setPen(QColor(190, 200, 210));
  p->drawText(QRectF(8, 19, kWidth - 16, 16), Qt::AlignLeft | Qt::AlignVCenter, module_);
  if (blockwise_) {  // badge: runs block by block under a memory budget
    const QRectF badge(kWidth - 44, 5, 38, 13);
    p->setPen(Qt::NoPen);
    p->setBrush(QColor(70, 110, 160));
    p->drawRoundedRect(badge, 3, 3);
    p->setPen(Qt::white);
    p->drawText(badge, Qt::AlignCenter, "blocks");
  }
  // Port labels.
  p->setPen(QColor(220, 220, 220));
  for (PortItem* port : inputs_) {
    p->drawText(QRectF(12, port->y() - kRow / 2, kWidth / 2 - 12, kRow), Qt::AlignLeft | Qt::AlignVCenter,
                port->port());
  }
  for (PortItem* port : outputs_) {
    p->drawText(QRectF(kWidth / 2, port->y() - kRow / 2, kWidth / 2 - 12, kRow),
                Qt::AlignRight | Qt::AlignVCenter, port->port());
  }
  // Footer: state, progress while running, error message.
  const QRectF footer(6, height_ - kFooter + 3, kWidth - 12, kFooter - 8);
  p->setPen(Qt::NoPen);
  p->setBrush(QColor(30, 32, 36));
  p->drawRoundedRect(footer, 3, 3);
  if (status_.state == NodeState::Running || status_.state == NodeState::Done || status_.state == NodeState::Cached) {
    const double frac = status_.state == NodeState::Running ? std::clamp(status_.progress, 0.0, 1.0) : 1.0;
    p->setBrush(sc);
    p->drawRoundedRect(QRectF(footer.left(), footer.top(), footer.width() * frac, footer.height()), 3, 3);
  } else {
    p->setBrush(sc);
    p->drawEllipse(QPointF(footer.left() + 8, footer.center().y()), 4, 4);
  }
  QString text = to_string(status_.state);
  if (status_.state == NodeState::Running) text += QString(" %1%").arg(static_cast<int>(status_.progress * 100));
  if (status_.state == NodeState::Error && !status_.message.empty()) text += ": " + qstr(status_.message);
  p->setPen(Qt::white);
  p->drawText(footer.adjusted(18, 0, -4, 0), Qt::AlignLeft | Qt::AlignVCenter,
              p->fontMetrics().elidedText(text, Qt::ElideRight, static_cast<int>(footer.width() - 22)));
}

QVariant NodeItem::itemChange(GraphicsItemChange change, const QVariant& value) {
  if (change == ItemPositionHasChanged) scene_->node_moved(id_);
  if (change == ItemSelectedHasChanged) update();
  return QGraphicsItem::itemChange(change, value);
}

// ---------------------------------------------------------------- EdgeItem

EdgeItem::EdgeItem(QString to_node, QString to_port, QColor color)
    : to_node_(std::move(to_node)), to_port_(std::move(to_port)), color_(color) {
  setFlags(ItemIsSelectable);
  setZValue(0);
  setToolTip("connection to " + to_node_ + "." + to_port_ + " (select and press Delete to remove)");
}

void EdgeItem::set_ends(QPointF a, QPointF b) {
  QPainterPath path(a);
  const qreal dx = std::max(40.0, std::abs(b.x() - a.x()) * 0.5);
  path.cubicTo(a + QPointF(dx, 0), b - QPointF(dx, 0), b);
  setPath(path);
}

void EdgeItem::paint(QPainter* p, const QStyleOptionGraphicsItem*, QWidget*) {
  p->setRenderHint(QPainter::Antialiasing);
  p->setPen(QPen(isSelected() ? QColor(255, 255, 255) : color_, isSelected() ? 4 : 2.5));
  p->setBrush(Qt::NoBrush);
  p->drawPath(path());
}

// ---------------------------------------------------------------- NodeScene

NodeScene::NodeScene(PipelineDocument* doc, RunController* run, QObject* parent)
    : QGraphicsScene(parent), doc_(doc), run_(run) {
  setSceneRect(-5000, -5000, 10000, 10000);
  connect(doc_, &PipelineDocument::graph_changed, this, &NodeScene::sync);
  connect(doc_, &PipelineDocument::document_reset, this, &NodeScene::sync);
  connect(doc_, &PipelineDocument::nodes_moved, this, &NodeScene::sync_positions);
  if (run_) connect(run_, &RunController::node_status_changed, this, &NodeScene::update_status);
  connect(this, &QGraphicsScene::selectionChanged, this, [this] {
    if (!syncing_) emit node_selection_changed(selected_node_ids());
  });
  sync();
}

NodeScene::~NodeScene() {
  // Deleting the items must not emit selection changes to views that are already gone.
  blockSignals(true);
  syncing_ = true;
  clear();
}

QStringList NodeScene::selected_node_ids() const {
  QStringList ids;
  for (const QString& id : doc_->node_ids()) {
    if (NodeItem* n = nodes_.value(id); n && n->isSelected()) ids << id;
  }
  return ids;
}

void NodeScene::select_nodes(const QStringList& ids) {
  syncing_ = true;
  clearSelection();
  for (const QString& id : ids) {
    if (NodeItem* n = nodes_.value(id)) n->setSelected(true);
  }
  syncing_ = false;
  emit node_selection_changed(selected_node_ids());
}

void NodeScene::sync() {
  const QStringList selected = selected_node_ids();
  syncing_ = true;
  // Remove items of nodes that are gone or changed module; add missing ones.
  for (auto it = nodes_.begin(); it != nodes_.end();) {
    const PipelineNode* n = doc_->pipeline().find(it.key().toStdString());
    if (!n || qstr(n->module) != it.value()->module()) {
      delete it.value();
      it = nodes_.erase(it);
    } else {
      ++it;
    }
  }
  for (const auto& n : doc_->pipeline().nodes()) {
    const QString id = qstr(n.id);
    if (nodes_.contains(id)) continue;
    auto* item = new NodeItem(this, id, qstr(n.module), doc_->registry().find(n.module));
    nodes_.insert(id, item);
    addItem(item);
    if (run_) item->set_status(run_->status(id));
  }
  for (auto it = nodes_.begin(); it != nodes_.end(); ++it) it.value()->setPos(doc_->position(it.key()));
  rebuild_edges();
  for (const QString& id : selected) {
    if (NodeItem* n = nodes_.value(id)) n->setSelected(true);
  }
  syncing_ = false;
  emit node_selection_changed(selected_node_ids());
}

void NodeScene::sync_positions() {
  syncing_ = true;
  for (auto it = nodes_.begin(); it != nodes_.end(); ++it) it.value()->setPos(doc_->position(it.key()));
  syncing_ = false;
  rebuild_edges();
}

void NodeScene::rebuild_edges() {
  for (EdgeItem* e : edges_) delete e;
  edges_.clear();
  for (const auto& n : doc_->pipeline().nodes()) {
    NodeItem* to = nodes_.value(qstr(n.id));
    if (!to) continue;
    for (const auto& [port, ref] : n.inputs) {
      NodeItem* from = nodes_.value(qstr(ref.node));
      PortItem* out = from ? from->output(qstr(ref.port)) : nullptr;
      PortItem* in = to->input(qstr(port));
      if (!out || !in) continue;
      auto* e = new EdgeItem(qstr(n.id), qstr(port), out->color());
      e->set_ends(out->anchor(), in->anchor());
      addItem(e);
      edges_.push_back(e);
    }
  }
}

void NodeScene::node_moved(const QString&) {
  if (syncing_) return;
  // Cheap enough for editor-sized graphs: recompute every edge path.
  for (EdgeItem* e : edges_) {
    const PipelineNode* n = doc_->pipeline().find(e->to_node().toStdString());
    if (!n) continue;
    auto it = n->inputs.find(e->to_port().toStdString());
    if (it == n->inputs.end()) continue;
    NodeItem* from = nodes_.value(qstr(it->second.node));
    NodeItem* to = nodes_.value(e->to_node());
    if (!from || !to) continue;
    PortItem* out = from->output(qstr(it->second.port));
    PortItem* in = to->input(e->to_port());
    if (out && in) e->set_ends(out->anchor(), in->anchor());
  }
}

void NodeScene::update_status(const QString& node) {
  if (NodeItem* n = nodes_.value(node); n && run_) n->set_status(run_->status(node));
}

void NodeScene::delete_selection() {
  QStringList ids = selected_node_ids();
  QList<QPair<QString, QString>> inputs;
  for (QGraphicsItem* item : selectedItems()) {
    if (auto* e = qgraphicsitem_cast<EdgeItem*>(item)) inputs.append({e->to_node(), e->to_port()});
  }
  if (!ids.isEmpty() || !inputs.isEmpty()) doc_->undo_stack()->beginMacro("Delete selection");
  for (const auto& [node, port] : inputs) {
    if (!ids.contains(node)) doc_->disconnect_port(node, port);
  }
  if (!ids.isEmpty()) doc_->remove_nodes(ids);
  if (!ids.isEmpty() || !inputs.isEmpty()) doc_->undo_stack()->endMacro();
}

PortItem* NodeScene::port_at(QPointF pos) const {
  for (QGraphicsItem* item : items(QRectF(pos - QPointF(5, 5), QSizeF(10, 10)))) {
    if (auto* p = qgraphicsitem_cast<PortItem*>(item)) return p;
  }
  return nullptr;
}

void NodeScene::mousePressEvent(QGraphicsSceneMouseEvent* e) {
  if (e->button() == Qt::LeftButton) {
    if (PortItem* port = port_at(e->scenePos())) {
      drag_port_ = port;
      press_pos_ = e->scenePos();
      drag_line_ = new QGraphicsPathItem;
      drag_line_->setPen(QPen(port->color(), 2, Qt::DashLine));
      drag_line_->setZValue(3);
      addItem(drag_line_);
      e->accept();
      return;
    }
  }
  QGraphicsScene::mousePressEvent(e);
}

void NodeScene::mouseMoveEvent(QGraphicsSceneMouseEvent* e) {
  if (drag_port_) {
    const QPointF a = drag_port_->anchor(), b = e->scenePos();
    QPainterPath path(a);
    const qreal dx = std::max(40.0, std::abs(b.x() - a.x()) * 0.5) * (drag_port_->is_output() ? 1 : -1);
    path.cubicTo(a + QPointF(dx, 0), b - QPointF(dx, 0), b);
    drag_line_->setPath(path);
    return;
  }
  QGraphicsScene::mouseMoveEvent(e);
}

void NodeScene::mouseReleaseEvent(QGraphicsSceneMouseEvent* e) {
  if (drag_port_) {
    PortItem* from = drag_port_;
    drag_port_ = nullptr;
    delete drag_line_;
    drag_line_ = nullptr;
    const bool click = (e->scenePos() - press_pos_).manhattanLength() < 4;
    if (click) {
      if (from->is_output()) emit output_port_clicked(from->node(), from->port());
      return;
    }
    PortItem* to = port_at(e->scenePos());
    if (!to) {
      // Dragging a connected input into empty space disconnects it.
      if (!from->is_output()) doc_->disconnect_port(from->node(), from->port());
      return;
    }
    if (to->is_output() == from->is_output()) {
      show_refusal(e->scenePos(), "connect an output (circle) to an input (square)");
      return;
    }
    PortItem* out = from->is_output() ? from : to;
    PortItem* in = from->is_output() ? to : from;
    const QString reason = doc_->connect_ports(out->node(), out->port(), in->node(), in->port());
    if (!reason.isEmpty()) show_refusal(e->scenePos(), reason);
    return;
  }
  QGraphicsScene::mouseReleaseEvent(e);
  // Commit a drag of nodes as one undoable move.
  QMap<QString, QPointF> moved;
  for (auto it = nodes_.begin(); it != nodes_.end(); ++it) {
    if (it.value()->pos() != doc_->position(it.key())) moved.insert(it.key(), it.value()->pos());
  }
  if (!moved.isEmpty()) doc_->move_nodes(moved);
}

void NodeScene::show_refusal(QPointF at, const QString& text) {
  emit message("Connection refused: " + text);
  auto* label = new QGraphicsSimpleTextItem("✕ " + text);
  label->setBrush(QColor(255, 90, 90));
  QFont f = label->font();
  f.setBold(true);
  label->setFont(f);
  label->setPos(at + QPointF(10, -20));
  label->setZValue(10);
  addItem(label);
  QTimer::singleShot(4000, this, [this, label] {
    if (items().contains(label)) {
      removeItem(label);
      delete label;
    }
  });
}

// ---------------------------------------------------------------- NodeView

NodeView::NodeView(NodeScene* scene, QWidget* parent) : QGraphicsView(scene, parent), scene_(scene) {
  setRenderHint(QPainter::Antialiasing);
  setDragMode(QGraphicsView::RubberBandDrag);
  setRubberBandSelectionMode(Qt::IntersectsItemShape);
  setTransformationAnchor(QGraphicsView::AnchorUnderMouse);
  setViewportUpdateMode(QGraphicsView::FullViewportUpdate);
  setAcceptDrops(true);
  setBackgroundBrush(QColor(36, 38, 42));
}

void NodeView::fit_all() {
  // The nodes (the curves of connections between bands may bulge out a little).
  QRectF r;
  for (QGraphicsItem* item : scene_->items())
    if (dynamic_cast<NodeItem*>(item)) r = r.united(item->sceneBoundingRect());
  if (r.isEmpty()) r = QRectF(-200, -150, 400, 300);
  r.adjust(-20, -20, 20, 20);
  const QRect vp = viewport()->rect();
  const double fit = std::min(vp.width() / r.width(), vp.height() / r.height());
  resetTransform();
  if (fit >= kLegibleZoom) {
    // All of it, never magnified beyond 1:1.
    const double z = std::min(fit, 1.0);
    scale(z, z);
    centerOn(r.center());
    return;
  }
  // Too large to show whole at a legible size: its width if that fits, from the top.
  const double z = std::clamp(vp.width() / r.width(), kLegibleZoom, 1.0);
  scale(z, z);
  const double half_w = 0.5 * vp.width() / z, half_h = 0.5 * vp.height() / z;
  const QRectF nodes = r.adjusted(20, 20, -20, -20);  // without the margins
  centerOn(QPointF(nodes.width() > 2 * half_w ? r.left() + half_w : r.center().x(), r.top() + half_h));
}

int NodeView::legible_columns(int width) {
  const double w = width / kLegibleZoom - 40;  // fit_all's margins
  const double step = PipelineDocument::kLayoutColumnStep, node = kWidth;
  return std::max(2, static_cast<int>((w - node) / step) + 1);
}

void NodeView::zoom(double factor) {
  const double s = transform().m11() * factor;
  if (s < 0.1 || s > 4.0) return;
  scale(factor, factor);
}

QPointF NodeView::visible_center() const { return mapToScene(viewport()->rect().center()); }

void NodeView::wheelEvent(QWheelEvent* e) {
  zoom(std::pow(1.0015, e->angleDelta().y()));
  e->accept();
}

void NodeView::mousePressEvent(QMouseEvent* e) {
  if (e->button() == Qt::MiddleButton) {
    panning_ = true;
    pan_last_ = e->pos();
    setCursor(Qt::ClosedHandCursor);
    e->accept();
    return;
  }
  QGraphicsView::mousePressEvent(e);
}

void NodeView::mouseMoveEvent(QMouseEvent* e) {
  if (panning_) {
    const QPoint d = e->pos() - pan_last_;
    pan_last_ = e->pos();
    horizontalScrollBar()->setValue(horizontalScrollBar()->value() - d.x());
    verticalScrollBar()->setValue(verticalScrollBar()->value() - d.y());
    e->accept();
    return;
  }
  QGraphicsView::mouseMoveEvent(e);
}

void NodeView::mouseReleaseEvent(QMouseEvent* e) {
  if (panning_ && e->button() == Qt::MiddleButton) {
    panning_ = false;
    unsetCursor();
    e->accept();
    return;
  }
  QGraphicsView::mouseReleaseEvent(e);
}

void NodeView::dragEnterEvent(QDragEnterEvent* e) {
  if (e->mimeData()->hasFormat(kModuleMime)) e->acceptProposedAction();
}

void NodeView::dragMoveEvent(QDragMoveEvent* e) {
  if (e->mimeData()->hasFormat(kModuleMime)) e->acceptProposedAction();
}

void NodeView::dropEvent(QDropEvent* e) {
  if (!e->mimeData()->hasFormat(kModuleMime)) return;
  const QString module = QString::fromUtf8(e->mimeData()->data(kModuleMime));
  QString error;
  const QString id = scene_->document()->add_node(module, mapToScene(e->pos()), &error);
  if (id.isEmpty()) {
    emit scene_->message(error);
  } else {
    scene_->select_nodes({id});
  }
  e->acceptProposedAction();
}

void NodeView::drawBackground(QPainter* p, const QRectF& rect) {
  QGraphicsView::drawBackground(p, rect);
  const qreal step = 40;
  p->setPen(QPen(QColor(50, 53, 58), 1));
  for (qreal x = std::floor(rect.left() / step) * step; x < rect.right(); x += step) {
    p->drawLine(QPointF(x, rect.top()), QPointF(x, rect.bottom()));
  }
  for (qreal y = std::floor(rect.top() / step) * step; y < rect.bottom(); y += step) {
    p->drawLine(QPointF(rect.left(), y), QPointF(rect.right(), y));
  }
}

}  // namespace skel::gui
