#include "graph_edit_mode.hpp"

#include <QComboBox>
#include <QDir>
#include <QDockWidget>
#include <QGridLayout>
#include <QHBoxLayout>
#include <QLabel>
#include <QMessageBox>
#include <QMouseEvent>
#include <QPushButton>
#include <QRubberBand>
#include <QSignalBlocker>
#include <QUndoView>
#include <QVBoxLayout>

#include <vtkActor.h>
#include <vtkCamera.h>
#include <vtkRenderer.h>
#include <vtkSmartPointer.h>

#include <cmath>
#include <cstdlib>

#include "main_window.hpp"
#include "run_controller.hpp"
#include "skel/error.hpp"
#include "skel/volume.hpp"
#include "views/view3d.hpp"
#include "skel_render/vtk_convert.hpp"

namespace skel::gui {

struct GraphEditMode::Overlay {
  vtkSmartPointer<vtkActor> nodes, edges, tour_end, tour_partner, tour_line;
};

GraphEditMode::GraphEditMode(MainWindow* window) : InteractionMode(window) {
  connect(window_->document(), &PipelineDocument::document_reset, this, &GraphEditMode::stop);
  bind_key(Qt::Key_Delete, [this] { session_->delete_selected(); });
  bind_key(Qt::Key_Backspace, [this] { session_->delete_selected(); });
  bind_key(Qt::Key_C, [this] { session_->connect_selected(); });
  bind_key(Qt::Key_S, [this] { session_->split_selected(); });
  bind_key(Qt::Key_M, [this] { session_->merge_selected(); });
  bind_key(Qt::Key_N, [this] { next_and_focus(false); });
  for (int key : {Qt::Key_Return, Qt::Key_Enter, Qt::Key_A}) bind_key(key, [this] { session_->accept_dangling(); });
  for (int key : {Qt::Key_Space, Qt::Key_K}) bind_key(key, [this] { next_and_focus(true); });
  bind_key(Qt::Key_Escape, [this] { session_->clear_selection(); });
}

GraphEditMode::~GraphEditMode() { stop(); }

QUndoStack* GraphEditMode::undo_stack() const { return session_->undo_stack(); }

QString GraphEditMode::journal_dir() const { return journal_dir_.isEmpty() ? default_dir() : journal_dir_; }

bool GraphEditMode::start(const QString& node, const QString& port, const QString& journal_path) {
  stop();
  RunController* run = window_->runner();
  auto graph = std::dynamic_pointer_cast<const SpatialGraph>(run->output(node, port));
  if (!graph) {
    log("Edit mode: " + node + "." + port + " is not a computed graph output (run the pipeline first)", true);
    return false;
  }
  // Image data of the same pipeline: the original image (first non-binary volume upstream) under the
  // graph, the mask for routed connections and the distance map for radii.
  graph::EditContext context;
  const Pipeline& p = window_->document()->pipeline();
  background_.clear();
  mask_port_.clear();
  distance_port_.clear();
  try {
    const auto upstream = p.upstream_closure({node.toStdString()});
    for (const auto& id : p.topological_order()) {
      if (!upstream.count(id)) continue;
      const ModuleSpec* spec = window_->document()->spec(QString::fromStdString(id));
      if (!spec) continue;
      for (const auto& out : spec->outputs()) {
        const QString qid = QString::fromStdString(id), qport = QString::fromStdString(out.name);
        DataPtr d = run->output(qid, qport);
        if (!d) continue;
        if (auto m = std::dynamic_pointer_cast<const VolumeU8>(d); m && out.name == "mask") {
          context.mask = m;  // the last mask upstream (e.g. the largest component)
          mask_port_ = qid + "." + qport;
        } else if (auto f = std::dynamic_pointer_cast<const VolumeF32>(d); f && out.name == "distance") {
          context.distance = f;
          distance_port_ = qid + "." + qport;
        } else if (background_.isEmpty() && d->type_id().rfind("volume.", 0) == 0 && out.name != "distance" &&
                   !render::is_binary_volume(*d)) {
          background_ = qid + "." + qport;
        }
      }
    }
  } catch (const std::exception&) {
    // An invalid pipeline has no upstream data to offer: edit without it.
  }

  session_ = std::make_unique<GraphEditSession>(node + "." + port, *graph, context);
  node_ = node;
  port_ = port;
  const QString journal =
      journal_path.isEmpty() ? QDir(journal_dir()).filePath(node + "." + port + ".edits.yaml") : journal_path;
  GraphEditSession::Resume resume = GraphEditSession::Resume::Replay;
  const int entries = GraphEditSession::journal_entries(journal);
  if (entries > 0) {
    ResumePolicy policy = resume_policy_;
    const QByteArray env = qgetenv("SKELFLOW_EDIT_RESUME");
    if (policy == ResumePolicy::Ask && env == "replay") policy = ResumePolicy::Replay;
    if (policy == ResumePolicy::Ask && env == "restart") policy = ResumePolicy::StartOver;
    if (policy == ResumePolicy::Ask) {
      const auto answer = QMessageBox::question(
          window_, "Resume editing",
          QString("The edit journal %1 holds %2 entries from an earlier session.\n\nResume (replay them) or start "
                  "over (the old journal is kept as a .bak file)?")
              .arg(journal)
              .arg(entries),
          QMessageBox::Yes | QMessageBox::No | QMessageBox::Cancel, QMessageBox::Yes);
      if (answer == QMessageBox::Cancel) {
        session_.reset();
        return false;
      }
      policy = answer == QMessageBox::Yes ? ResumePolicy::Replay : ResumePolicy::StartOver;
    }
    resume = policy == ResumePolicy::Replay ? GraphEditSession::Resume::Replay : GraphEditSession::Resume::StartOver;
  }
  QStringList report;
  try {
    session_->open_journal(journal, resume, &report);
  } catch (const std::exception& e) {
    log("Edit mode: " + QString::fromUtf8(e.what()), true);
    session_.reset();
    return false;
  }
  for (const QString& line : report) log("Edit journal: " + line);

  connect(session_.get(), &GraphEditSession::graph_changed, this, &GraphEditMode::refresh_graph);
  connect(session_.get(), &GraphEditSession::selection_changed, this, &GraphEditMode::refresh_overlay);
  connect(session_.get(), &GraphEditSession::dangling_changed, this, &GraphEditMode::refresh_overlay);
  connect(session_.get(), &GraphEditSession::message, this, [this](const QString& m, bool error) { log(m, error); });
  connect(session_->undo_stack(), &QUndoStack::indexChanged, this, &GraphEditMode::update_status);

  // The 3D view: background image, the edited graph as lines, the original hidden.
  if (!background_.isEmpty()) {
    const int dot = background_.lastIndexOf('.');
    QSignalBlocker block(view_);
    if (view_->show_data(background_, run->output(background_.left(dot), background_.mid(dot + 1))))
      view_->set_volume_mode(background_, VolumeMode::Mip);
  }
  object_ = node + "." + port + " [edit]";
  original_was_visible_ = view_->has_object(node + "." + port) && view_->object_visible(node + "." + port);
  if (original_was_visible_) view_->set_object_visible(node + "." + port, false);
  {
    QSignalBlocker block(view_);
    view_->show_data(object_, session_->graph_ptr());
    view_->set_graph_mode(object_, GraphMode::Lines);
  }

  overlay_ = std::make_unique<Overlay>();
  vtkRenderer* overlay = open_overlay();
  overlay_->nodes = make_overlay_actor({1.0, 0.95, 0.2}, 12, 2);
  overlay_->edges = make_overlay_actor({1.0, 0.6, 0.1}, 8, 5);
  overlay_->tour_end = make_overlay_actor({1.0, 0.2, 0.9}, 18, 2);
  overlay_->tour_partner = make_overlay_actor({0.2, 1.0, 1.0}, 18, 2);
  overlay_->tour_line = make_overlay_actor({0.2, 1.0, 1.0}, 6, 3);
  for (auto* a : {overlay_->edges.Get(), overlay_->nodes.Get(), overlay_->tour_line.Get(), overlay_->tour_end.Get(),
                  overlay_->tour_partner.Get()})
    overlay->AddActor(a);
  take_input();
  build_docks();
  refresh_overlay();
  update_status();
  log("Edit mode on " + node + "." + port + " (journal " + journal + ")" +
      (background_.isEmpty() ? QString() : ", image " + background_) +
      (mask_port_.isEmpty() ? QString() : ", mask " + mask_port_));
  emit started();
  return true;
}

void GraphEditMode::stop() {
  if (!session_) return;
  if (history_) history_->setStack(nullptr);
  release();  // event filter, overlay layer, docks
  overlay_.reset();
  panel_dock_ = history_dock_ = nullptr;
  history_ = nullptr;
  status_ = nullptr;
  route_ = nullptr;
  {
    QSignalBlocker block(view_);
    view_->remove_object(object_);  // it aliases the session's graph: remove before the session goes
    if (original_was_visible_) view_->set_object_visible(node_ + "." + port_, true);
  }
  session_.reset();
  log("Left edit mode on " + node_ + "." + port_);
  emit stopped();
}

void GraphEditMode::build_docks() {
  auto* panel = new QWidget;
  auto* v = new QVBoxLayout(panel);
  status_ = new QLabel(panel);
  status_->setWordWrap(true);
  status_->setTextInteractionFlags(Qt::TextSelectableByMouse);
  v->addWidget(status_);
  auto* grid = new QGridLayout;
  int k = 0;
  auto button = [&](const QString& text, auto slot) {
    auto* b = new QPushButton(text, panel);
    b->setFocusPolicy(Qt::NoFocus);
    connect(b, &QPushButton::clicked, this, slot);
    grid->addWidget(b, k / 3, k % 3);
    ++k;
    return b;
  };
  button("Next end (N)", [this] { next_and_focus(false); });
  button("Accept (A)", [this] { session_->accept_dangling(); });
  button("Skip (K)", [this] { next_and_focus(true); });
  button("Delete (Del)", [this] { session_->delete_selected(); });
  button("Connect (C)", [this] { session_->connect_selected(); });
  button("Split (S)", [this] { session_->split_selected(); });
  button("Merge (M)", [this] { session_->merge_selected(); });
  button("Undo (Ctrl+Z)", [this] { session_->undo_stack()->undo(); });
  button("Redo (Ctrl+Shift+Z)", [this] { session_->undo_stack()->redo(); });
  v->addLayout(grid);
  auto* row = new QHBoxLayout;
  row->addWidget(new QLabel("Connect route", panel));
  route_ = new QComboBox(panel);
  route_->addItem("straight");
  if (session_->has_mask()) route_->addItem("mask");
  route_->setToolTip("straight: a line; mask: the shortest 26-path through the object mask");
  connect(route_, &QComboBox::currentTextChanged, this, [this](const QString& r) { session_->set_route(r); });
  row->addWidget(route_, 1);
  v->addLayout(row);
  auto* row2 = new QHBoxLayout;
  auto* save_b = new QPushButton("Save edits", panel);
  auto* leave_b = new QPushButton("Leave edit mode", panel);
  connect(save_b, &QPushButton::clicked, this, [this] { save(); });
  connect(leave_b, &QPushButton::clicked, this, &GraphEditMode::stop);
  row2->addWidget(save_b);
  row2->addWidget(leave_b);
  v->addLayout(row2);
  v->addStretch(1);
  panel_dock_ = add_dock("Graph editing", "graph_editing", panel);

  history_ = new QUndoView(session_->undo_stack());
  history_->setEmptyLabel("(graph as computed)");
  history_dock_ = add_dock("Edit history", "edit_history", history_);
}

void GraphEditMode::update_status() {
  if (!session_ || !status_) return;
  const SpatialGraph& g = session_->graph();
  QString sel;
  const auto nodes = session_->selected_nodes();
  const auto edges = session_->selected_edges();
  sel = QString("%1 node(s), %2 edge(s) selected").arg(nodes.size()).arg(edges.size());
  QString tour;
  if (const auto* d = session_->current_dangling()) {
    tour = QString("<br>Dangling end at [%1, %2, %3]: %4")
               .arg(d->position[0], 0, 'f', 1)
               .arg(d->position[1], 0, 'f', 1)
               .arg(d->position[2], 0, 'f', 1)
               .arg(d->has_partner ? QString("partner at %1 (angle %2°), A accepts, K skips")
                                         .arg(d->distance, 0, 'f', 2)
                                         .arg(d->angle_deg, 0, 'f', 0)
                                   : QString("no partner proposed, K skips"));
  }
  status_->setText(QString("<b>%1</b><br>%2 nodes, %3 edges; %4 step(s) in the history<br>Journal: %5<br>%6%7")
                       .arg(session_->name())
                       .arg(g.node_count())
                       .arg(g.edge_count())
                       .arg(session_->undo_stack()->index())
                       .arg(session_->journal_path().toHtmlEscaped())
                       .arg(sel)
                       .arg(tour));
}

void GraphEditMode::refresh_graph() {
  if (!session_) return;
  QSignalBlocker block(view_);
  view_->show_data(object_, session_->graph_ptr());
  refresh_overlay();
}

void GraphEditMode::refresh_overlay() {
  if (!session_ || !overlay_) return;
  const SpatialGraph& g = session_->graph();
  OverlayShape nodes, edges, end, partner, line;
  for (const auto& item : session_->selection()) {
    if (item.kind == GraphPick::Kind::Node) nodes.vertex(item.position);
    if (item.kind == GraphPick::Kind::EdgePoint) {
      edges.vertex(item.position);
      if (item.edge >= 0 && item.edge < g.edge_count()) edges.line(g.edges[item.edge].points);
    }
  }
  if (const auto* d = session_->current_dangling()) {
    end.vertex(d->position);
    if (d->has_partner) {
      partner.vertex(d->partner_position);
      line.line({d->position, d->partner_position});
    }
  }
  nodes.set(overlay_->nodes);
  edges.set(overlay_->edges);
  end.set(overlay_->tour_end);
  partner.set(overlay_->tour_partner);
  line.set(overlay_->tour_line);
  update_status();
  view_->render();
}

void GraphEditMode::next_and_focus(bool skip) {
  if (!session_) return;
  const bool ok = skip ? session_->skip_dangling() : session_->next_dangling();
  if (!ok) return;
  const auto* d = session_->current_dangling();
  if (!d) return;
  focus(d->position, d->has_partner ? d->distance : 10.0);
}

void GraphEditMode::focus(const Vec3& p, double extent) {
  vtkRenderer* ren = view_->renderer();
  vtkCamera* cam = ren->GetActiveCamera();
  double dop[3];
  cam->GetDirectionOfProjection(dop);
  double b[6];
  ren->ComputeVisiblePropBounds(b);
  const double diag = std::sqrt((b[1] - b[0]) * (b[1] - b[0]) + (b[3] - b[2]) * (b[3] - b[2]) + (b[5] - b[4]) * (b[5] - b[4]));
  // Far enough to see the gap and some context, close enough to judge it.
  const double dist = std::max(6.0 * extent, 0.25 * (std::isfinite(diag) ? diag : 100.0));
  cam->SetFocalPoint(p[0], p[1], p[2]);
  cam->SetPosition(p[0] - dop[0] * dist, p[1] - dop[1] * dist, p[2] - dop[2] * dist);
  ren->ResetCameraClippingRange();
  view_->render();
}

GraphPick GraphEditMode::pick(QPoint pos) const {
  if (!session_) return {};
  return pick_graph(session_->graph(), projection(), pos.x() + 0.5, pos.y() + 0.5, kPickRadius);
}

bool GraphEditMode::save(const QString& base_in) {
  if (!session_) return false;
  const QString base = base_in.isEmpty() ? QDir(journal_dir()).filePath(node_ + "." + port_ + ".edited") : base_in;
  try {
    const QStringList files = session_->save_graph(base);
    const QString id = session_->add_apply_edits_node(window_->document(), mask_port_, distance_port_);
    log("Saved the edited graph: " + files.join(", ") + "; journal " + session_->journal_path() + "; pipeline node " +
        id + " replays it after " + node_ + "." + port_);
  } catch (const std::exception& e) {
    log("Saving the edits failed: " + QString::fromUtf8(e.what()), true);
    return false;
  }
  update_status();
  return true;
}

bool GraphEditMode::mouse_press(QMouseEvent* m) {
  box_ = m->modifiers() & Qt::ShiftModifier;
  if (!box_) return false;
  if (!rubber_) rubber_ = new QRubberBand(QRubberBand::Rectangle, vtk_widget_);
  rubber_->setGeometry(QRect(press_pos(), QSize()));
  rubber_->show();
  return true;  // no camera rotation while drawing the box
}

bool GraphEditMode::mouse_move(QMouseEvent* m) {
  if (!pressed() || !box_) return false;
  rubber_->setGeometry(QRect(press_pos(), m->pos()).normalized());
  return true;
}

bool GraphEditMode::mouse_release(QMouseEvent* m, bool click) {
  if (box_) {
    rubber_->hide();
    const QRect r = QRect(press_pos(), m->pos()).normalized();
    const BoxSelection b = select_box(session_->graph(), projection(), r.left(), r.top(), r.right() + 1, r.bottom() + 1);
    std::vector<EditSelectionItem> items;
    for (int64_t n : b.nodes) {
      EditSelectionItem i;
      i.kind = GraphPick::Kind::Node;
      i.node = n;
      i.position = session_->graph().positions[n];
      items.push_back(i);
    }
    for (const auto& [e, pt] : b.edge_points) {
      EditSelectionItem i;
      i.kind = GraphPick::Kind::EdgePoint;
      i.edge = e;
      i.point = pt;
      i.position = session_->graph().edges[e].points[pt];
      items.push_back(i);
    }
    session_->add_to_selection(items);
    box_ = false;
    return true;
  }
  if (click) {
    const GraphPick p = pick(m->pos());
    if (m->modifiers() & Qt::ControlModifier) {
      if (p.valid()) session_->toggle(GraphEditSession::item_from_pick(p));
    } else if (p.valid()) {
      session_->set_selection({GraphEditSession::item_from_pick(p)});
    } else {
      session_->clear_selection();
    }
  }
  return false;  // the interactor ends its (empty) rotation
}

}  // namespace skel::gui
