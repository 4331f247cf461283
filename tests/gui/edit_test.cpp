// The graph edit mode of skelflow-gui (issue 10, thesis §6.1) under a virtual X server: open the
// vessel pipeline (small phantom), run it, enter edit mode on the pruned graph, pick with the mouse,
// box-select, tour to the next dangling end, accept its connection, undo, redo, save; check the
// saved .am/.vtp, the journal and the graph.apply_edits node (a re-run reproduces the edited graph).
// A second test runs gui_edit_crash_helper (the same edit-mode code in its own process), kills it
// with SIGKILL after a few edits and checks that the journal holds every one of them.
//
// Screenshots go to <build>/gui_screenshots; with SKELFLOW_UPDATE_DOC_IMAGES=1 also to docs/images.
#include <gtest/gtest.h>

#include <QApplication>
#include <QDir>
#include <QDockWidget>
#include <QFileInfo>
#include <QProcess>
#include <QStandardPaths>
#include <QSurfaceFormat>
#include <QTemporaryDir>
#include <QTest>
#include <QUndoView>

#include <QVTKOpenGLNativeWidget.h>

#include <cmath>
#include <cstdlib>

#include "edit_session.hpp"
#include "edit_test_util.hpp"
#include "io/graph_io.hpp"
#include "main_window.hpp"
#include "modes/graph_edit_mode.hpp"
#include "skel/table.hpp"
#include "views/view3d.hpp"

using namespace skel::io;

using namespace skel;
using namespace skel::gui;

namespace {

bool g_have_display = false;

#define REQUIRE_DISPLAY() \
  if (!g_have_display) GTEST_SKIP() << "no X display (run through xvfb-run, as ctest does)"

void save_shot(const QImage& img, const QString& name) {
  const QString dir = QString(SKEL_BINARY_DIR) + "/gui_screenshots";
  QDir().mkpath(dir);
  ASSERT_TRUE(img.save(dir + "/" + name)) << name.toStdString();
  if (qgetenv("SKELFLOW_UPDATE_DOC_IMAGES") == "1") {
    ASSERT_TRUE(img.save(QString(SKEL_SOURCE_DIR) + "/docs/images/" + name)) << name.toStdString();
  }
}

// Number of distinct colours in an image (a blank view has 1-2).
int distinct_colours(const QImage& img) {
  QSet<QRgb> c;
  for (int y = 0; y < img.height(); y += 3)
    for (int x = 0; x < img.width(); x += 3) c.insert(img.pixel(x, y));
  return c.size();
}

bool run_and_wait(MainWindow& w, int ms) {
  w.run_all();
  const bool ok = QTest::qWaitFor([&] { return !w.runner()->is_running(); }, ms);
  QTest::qWait(50);  // queued status updates
  return ok;
}

int count_ops(const graph::Journal& j, graph::EditKind op) {
  return static_cast<int>(std::count_if(j.ops.begin(), j.ops.end(), [&](const auto& o) { return o.op == op; }));
}

}  // namespace

TEST(EditMode, TourConnectUndoRedoSaveAndReRun) {
  REQUIRE_DISPLAY();
  QTemporaryDir tmp;
  ASSERT_TRUE(tmp.isValid());
  const QString pipeline = write_small_vessel_pipeline(tmp.path());
  ASSERT_FALSE(pipeline.isEmpty());

  MainWindow w;
  w.resize(1400, 900);
  w.runner()->set_threads(2);
  ASSERT_TRUE(w.open_file(pipeline));
  w.show();
  ASSERT_TRUE(QTest::qWaitForWindowExposed(&w));
  ASSERT_TRUE(run_and_wait(w, 240000));
  ASSERT_EQ(w.runner()->status("pruned").state, NodeState::Done) << w.log_text().toStdString();

  GraphEditMode* em = w.graph_edit();
  em->set_journal_dir(tmp.path());
  em->set_resume_policy(GraphEditMode::ResumePolicy::Replay);
  ASSERT_TRUE(w.edit_graph("pruned", "graph")) << w.log_text().toStdString();
  ASSERT_TRUE(em->active());
  GraphEditSession* s = em->session();
  QWidget* vtk = em->vtk_widget();
  ASSERT_NE(vtk, nullptr);
  EXPECT_EQ(em->background_name(), "phantom.image");  // the original image under the graph (MIP)
  EXPECT_TRUE(s->has_mask());
  ASSERT_NE(em->history_dock(), nullptr);
  ASSERT_NE(em->history_view(), nullptr);
  const QString journal = QDir(tmp.path()).filePath("pruned.graph.edits.yaml");
  EXPECT_EQ(s->journal_path(), journal);
  EXPECT_TRUE(QFileInfo::exists(journal));
  const int64_t e0 = s->graph().edge_count();
  ASSERT_GT(e0, 10);
  w.view3d()->reset_camera();
  QTest::qWait(50);

  // Mouse picking: a click on a node's screen position selects that node; Ctrl+click on another
  // adds it; Esc clears; a Shift+drag box selects what lies in it.
  const SpatialGraph& g = s->graph();
  int64_t target = -1;
  for (int64_t n = 0; n < g.node_count() && target < 0; ++n) {
    const auto sp = em->screen_position(g.positions[n]);
    if (sp && em->pick(*sp).node == n) target = n;
  }
  ASSERT_GE(target, 0);
  QTest::mouseClick(vtk, Qt::LeftButton, Qt::NoModifier, *em->screen_position(g.positions[target]));
  ASSERT_EQ(s->selection().size(), 1u);
  EXPECT_EQ(s->selection()[0].kind, GraphPick::Kind::Node);
  EXPECT_EQ(s->selection()[0].node, target);
  QTest::keyClick(vtk, Qt::Key_Escape);
  EXPECT_TRUE(s->selection().empty());
  const QPoint c(vtk->width() / 2, vtk->height() / 2);
  QTest::mousePress(vtk, Qt::LeftButton, Qt::ShiftModifier, c - QPoint(80, 80));
  QTest::mouseMove(vtk, c);
  QTest::mouseRelease(vtk, Qt::LeftButton, Qt::ShiftModifier, c + QPoint(80, 80));
  const auto box = select_box(g, em->projection(), c.x() - 80, c.y() - 80, c.x() + 81, c.y() + 81);
  EXPECT_EQ(s->selection().size(), box.nodes.size() + box.edge_points.size());
  EXPECT_GT(s->selection().size(), 0u);
  save_shot(em->vtk_widget() ? w.view3d()->grab_image() : QImage(), "editing_box_selection.png");
  QTest::keyClick(vtk, Qt::Key_Escape);

  // Tour: N goes to the best-scored dangling end and selects it with its proposed partner.
  auto ends = graph::find_dangling_ends(s->graph());
  const bool natural_gap = std::any_of(ends.begin(), ends.end(), [](const auto& d) { return d.has_partner; });
  ASSERT_TRUE(natural_gap) << "the small vessel phantom has no gap with a proposed partner";
  QTest::keyClick(vtk, Qt::Key_N);
  const graph::DanglingEnd* d = s->current_dangling();
  ASSERT_NE(d, nullptr);
  ASSERT_TRUE(d->has_partner);
  EXPECT_EQ(d->node, ends.front().node);
  const Vec3 end_pos = d->position, partner_pos = d->partner_position;
  // Connecting to a point inside an edge splits that edge first: one or two edges more.
  const int64_t added = d->partner_is_node ? 1 : 2;
  EXPECT_EQ(s->selection().size(), 2u);
  QTest::qWait(50);
  save_shot(w.view3d()->grab_image(), "editing_tour.png");
  save_shot(w.grab().toImage(), "editing_window.png");
  EXPECT_GT(distinct_colours(w.view3d()->grab_image()), 30);

  // Accept (A) connects it: `added` edges more, one undo step, one journal entry.
  QTest::keyClick(vtk, Qt::Key_A);
  EXPECT_EQ(s->graph().edge_count(), e0 + added);
  EXPECT_EQ(s->undo_stack()->count(), 1);
  EXPECT_TRUE(s->graph().check_invariants().empty());
  // Undo / redo through the keys of the 3D view (not the pipeline's undo stack).
  const int doc_undo = w.document()->undo_stack()->count();
  QTest::keyClick(vtk, Qt::Key_Z, Qt::ControlModifier);
  EXPECT_EQ(s->graph().edge_count(), e0);
  EXPECT_EQ(s->undo_stack()->index(), 0);
  QTest::keyClick(vtk, Qt::Key_Z, Qt::ControlModifier | Qt::ShiftModifier);
  EXPECT_EQ(s->graph().edge_count(), e0 + added);
  EXPECT_EQ(s->undo_stack()->index(), 1);
  EXPECT_EQ(w.document()->undo_stack()->count(), doc_undo);
  EXPECT_EQ(em->history_view()->stack(), s->undo_stack());
  QTest::qWait(50);
  save_shot(w.view3d()->grab_image(), "editing_connected.png");

  // Save: .am and .vtp of the edited graph, the journal, and graph.apply_edits in the pipeline.
  const size_t nodes_before_save = w.document()->pipeline().nodes().size();
  ASSERT_TRUE(em->save()) << w.log_text().toStdString();
  const size_t nodes_after_first_save = w.document()->pipeline().nodes().size();
  EXPECT_EQ(nodes_after_first_save, nodes_before_save + 1);  // graph.apply_edits
  const QString base = QDir(tmp.path()).filePath("pruned.graph.edited");
  for (const char* ext : {".am", ".vtp"}) {
    const std::string path = (base + ext).toStdString();
    const SpatialGraph saved = read_graph(path, graph_format_from_path(path));
    EXPECT_EQ(saved.edge_count(), e0 + added) << path;
    EXPECT_EQ(saved.node_count(), s->graph().node_count()) << path;
  }
  const graph::Journal j = graph::read_journal(journal.toStdString());
  ASSERT_EQ(j.ops.size(), 3u);
  EXPECT_EQ(j.ops[0].op, graph::EditKind::connect);
  EXPECT_EQ(j.ops[1].op, graph::EditKind::undo);
  EXPECT_EQ(j.ops[2].op, graph::EditKind::redo);
  ASSERT_TRUE(j.ops[0].from && j.ops[0].to);
  EXPECT_LT(std::hypot((*j.ops[0].from)[0] - end_pos[0], (*j.ops[0].from)[1] - end_pos[1], (*j.ops[0].from)[2] - end_pos[2]), 1e-3);
  EXPECT_LT(std::hypot((*j.ops[0].to)[0] - partner_pos[0], (*j.ops[0].to)[1] - partner_pos[1], (*j.ops[0].to)[2] - partner_pos[2]), 1e-3);
  const PipelineNode* apply = w.document()->pipeline().find("apply_edits");
  ASSERT_NE(apply, nullptr);
  EXPECT_EQ(apply->module, "graph.apply_edits");
  EXPECT_EQ(apply->inputs.at("graph").str(), "pruned.graph");
  EXPECT_EQ(w.document()->pipeline().find("stats")->inputs.at("graph").str(), "apply_edits.graph");
  EXPECT_EQ(w.document()->pipeline().find("save_am")->inputs.at("graph").str(), "apply_edits.graph");
  // Saving again does not add a second node.
  ASSERT_TRUE(em->save());
  EXPECT_EQ(w.document()->pipeline().nodes().size(), nodes_after_first_save);

  // A re-run replays the journal on the recomputed graph: the manual work is kept.
  em->stop();
  EXPECT_FALSE(em->active());
  ASSERT_TRUE(run_and_wait(w, 240000));
  auto replayed = std::dynamic_pointer_cast<const SpatialGraph>(w.runner()->output("apply_edits", "graph"));
  ASSERT_NE(replayed, nullptr) << w.log_text().toStdString();
  EXPECT_EQ(replayed->edge_count(), e0 + added);
  auto table = std::dynamic_pointer_cast<const Table>(w.runner()->output("apply_edits", "table"));
  ASSERT_NE(table, nullptr);
  ASSERT_EQ(table->rows(), 3);
  for (int64_t r = 0; r < 3; ++r) EXPECT_EQ(table->cell(2, r), "applied");

  // Entering edit mode again resumes from the journal (policy: replay).
  ASSERT_TRUE(w.edit_graph("pruned", "graph"));
  EXPECT_EQ(em->session()->graph().edge_count(), e0 + added);
  EXPECT_EQ(em->session()->undo_stack()->count(), 1);
  em->session()->undo_stack()->undo();
  EXPECT_EQ(em->session()->graph().edge_count(), e0);
  EXPECT_EQ(graph::read_journal(journal.toStdString()).ops.size(), 4u);
}

// The edits of a killed process are all in the journal.
TEST(EditMode, JournalSurvivesSigkill) {
  REQUIRE_DISPLAY();
  QTemporaryDir tmp;
  ASSERT_TRUE(tmp.isValid());
  const QString pipeline = write_small_vessel_pipeline(tmp.path());
  QProcess p;
  p.setProcessChannelMode(QProcess::SeparateChannels);
  p.start(QString(SKEL_BINARY_DIR) + "/tests/gui/gui_edit_crash_helper", {pipeline, tmp.path()});
  ASSERT_TRUE(p.waitForStarted(10000));
  QByteArray out;
  ASSERT_TRUE(QTest::qWaitFor(
      [&] {
        p.waitForReadyRead(100);
        out += p.readAllStandardOutput();
        return out.contains("READY\n") || p.state() == QProcess::NotRunning;
      },
      240000));
  ASSERT_TRUE(out.contains("READY\n")) << out.toStdString() << p.readAllStandardError().toStdString();
  p.kill();  // SIGKILL on Unix: no destructor, no flush, no atexit
  ASSERT_TRUE(p.waitForFinished(10000));
  EXPECT_EQ(p.exitStatus(), QProcess::CrashExit);

  // The helper printed every journal entry as it wrote it ("OP <yaml>").
  QStringList expected;
  for (const QByteArray& line : out.split('\n')) {
    if (line.startsWith("OP ")) expected << QString::fromUtf8(line.mid(3));
  }
  ASSERT_GE(expected.size(), 5);
  const graph::Journal j = graph::read_journal(QDir(tmp.path()).filePath("pruned.graph.edits.yaml").toStdString());
  ASSERT_EQ(j.ops.size(), static_cast<size_t>(expected.size()));
  for (int i = 0; i < expected.size(); ++i) EXPECT_EQ(QString::fromStdString(j.ops[i].to_yaml()), expected[i]) << i;
  EXPECT_GE(count_ops(j, graph::EditKind::connect), 1);
  EXPECT_GE(count_ops(j, graph::EditKind::delete_edge), 1);
  EXPECT_GE(count_ops(j, graph::EditKind::split), 1);
  EXPECT_GE(count_ops(j, graph::EditKind::undo), 1);
}

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  const char* display = std::getenv("DISPLAY");
  g_have_display = display && *display;
  if (!g_have_display) return RUN_ALL_TESTS();
  setenv("QT_QPA_PLATFORM", "xcb", 0);
  QSurfaceFormat::setDefaultFormat(QVTKOpenGLNativeWidget::defaultFormat());
  QStandardPaths::setTestModeEnabled(true);
  QApplication app(argc, argv);
  QApplication::setOrganizationName("skelflow-test");
  QApplication::setApplicationName("gui_edit_test");
  return RUN_ALL_TESTS();
}
