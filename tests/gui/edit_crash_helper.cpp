// Helper of EditMode.JournalSurvivesSigkill: the real main window and edit mode in a process of its
// own. Opens the pipeline (argv[1]), runs it, enters edit mode on pruned.graph with the journal in
// argv[2], performs edits through the keys and mouse of the 3D view, prints "OP <journal entry>" for
// each as soon as it is done and finally "READY", then waits in the event loop to be killed.
#include <QApplication>
#include <QStandardPaths>
#include <QSurfaceFormat>
#include <QTest>

#include <QVTKOpenGLNativeWidget.h>

#include <cstdio>

#include "edit_session.hpp"
#include "main_window.hpp"
#include "modes/graph_edit_mode.hpp"
#include "views/view3d.hpp"

using namespace skel;
using namespace skel::gui;

namespace {
void say(const QString& line) {
  std::printf("%s\n", line.toUtf8().constData());
  std::fflush(stdout);
}
void fail(const QString& why) {
  say("FAILED " + why);
  std::exit(2);
}
// Clicks an interior vertex of some edge (different from `not_edge`) so that the pick selects it.
bool click_edge_point(GraphEditMode* em, QWidget* vtk, int64_t not_edge, int64_t* edge_out) {
  const SpatialGraph& g = em->session()->graph();
  for (int64_t e = 0; e < g.edge_count(); ++e) {
    if (e == not_edge || g.edges[e].points.size() < 5) continue;
    const auto pos = em->screen_position(g.edges[e].points[2]);
    if (!pos) continue;
    const GraphPick p = em->pick(*pos);
    if (p.kind != GraphPick::Kind::EdgePoint || p.edge != e || p.point <= 0 ||
        p.point + 1 >= static_cast<int64_t>(g.edges[e].points.size()))
      continue;
    QTest::mouseClick(vtk, Qt::LeftButton, Qt::NoModifier, *pos);
    const auto& sel = em->session()->selection();
    if (sel.size() == 1 && sel[0].edge == e) {
      *edge_out = e;
      return true;
    }
  }
  return false;
}
}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) return 1;
  setenv("QT_QPA_PLATFORM", "xcb", 0);
  QSurfaceFormat::setDefaultFormat(QVTKOpenGLNativeWidget::defaultFormat());
  QStandardPaths::setTestModeEnabled(true);
  QApplication app(argc, argv);
  QApplication::setOrganizationName("skelflow-test");
  QApplication::setApplicationName("gui_edit_crash_helper");
  MainWindow w;
  w.resize(1200, 800);
  w.runner()->set_threads(2);
  if (!w.open_file(QString::fromLocal8Bit(argv[1]))) fail("open");
  w.show();
  if (!QTest::qWaitForWindowExposed(&w)) fail("window");
  w.run_all();
  if (!QTest::qWaitFor([&] { return !w.runner()->is_running(); }, 240000)) fail("run");
  GraphEditMode* em = w.graph_edit();
  em->set_journal_dir(QString::fromLocal8Bit(argv[2]));
  em->set_resume_policy(GraphEditMode::ResumePolicy::StartOver);
  if (!w.edit_graph("pruned", "graph")) fail("edit mode: " + w.log_text());
  GraphEditSession* s = em->session();
  QWidget* vtk = em->vtk_widget();
  w.view3d()->reset_camera();
  QUndoStack* stack = s->undo_stack();
  auto last = [&] { say("OP " + stack->text(stack->index() - 1)); };

  // 1. Tour: next dangling end, accept the proposed connection.
  QTest::keyClick(vtk, Qt::Key_N);
  if (!s->current_dangling() || !s->current_dangling()->has_partner) fail("no dangling end with a partner");
  QTest::keyClick(vtk, Qt::Key_A);
  if (stack->index() != 1) fail("accept");
  last();
  // 2. Click an edge, Delete.
  int64_t e = -1;
  if (!click_edge_point(em, vtk, -1, &e)) fail("no pickable edge");
  QTest::keyClick(vtk, Qt::Key_Delete);
  if (stack->index() != 2) fail("delete");
  last();
  // 3. Click another edge, S splits it at the clicked vertex.
  if (!click_edge_point(em, vtk, -1, &e)) fail("no pickable edge");
  QTest::keyClick(vtk, Qt::Key_S);
  if (stack->index() != 3) fail("split");
  last();
  // 4. Ctrl+Z, 5. Ctrl+Shift+Z.
  QTest::keyClick(vtk, Qt::Key_Z, Qt::ControlModifier);
  if (stack->index() != 2) fail("undo");
  say("OP {op: undo}");
  QTest::keyClick(vtk, Qt::Key_Z, Qt::ControlModifier | Qt::ShiftModifier);
  if (stack->index() != 3) fail("redo");
  say("OP {op: redo}");
  say("READY");
  return QApplication::exec();  // until SIGKILL
}
