// Widget tests of skelflow-gui under a virtual X server (ctest runs them through xvfb-run): open or
// build a pipeline, run it, wait for completion, show outputs in the 3D view, save screenshots
// (into the build folder: gui_screenshots/) and check they are not uniform and that every node is
// drawn as done. Editing through the mouse (connect, refuse, undo), the properties panel and the
// palette are driven like a user would.
#include <gtest/gtest.h>

#include <QAction>
#include <QApplication>
#include <QDir>
#include <QDoubleSpinBox>
#include <QMessageBox>
#include <QMimeData>
#include <QPushButton>
#include <QProgressBar>
#include <QSet>
#include <QStandardPaths>
#include <QSurfaceFormat>
#include <QTableWidget>
#include <QElapsedTimer>
#include <QTest>
#include <QTimer>

#include <QVTKOpenGLNativeWidget.h>
#include <vtkProp.h>
#include <vtkPropCollection.h>
#include <vtkRenderer.h>

#include <cstdlib>
#include <filesystem>

#include "main_window.hpp"
#include "node_editor.hpp"
#include "palette.hpp"
#include "skel/plugin.hpp"
#include "properties_panel.hpp"
#include "skel/units.hpp"
#include "skel/volume.hpp"
#include "views/view3d.hpp"

using namespace skel;
using namespace skel::gui;

namespace {

bool g_have_display = false;

#define REQUIRE_DISPLAY() \
  if (!g_have_display) GTEST_SKIP() << "no X display (run through xvfb-run, as ctest does)"

QString shot_dir() {
  const QString dir = QString(SKEL_BINARY_DIR) + "/gui_screenshots";
  QDir().mkpath(dir);
  return dir;
}

bool done(NodeState s) { return s == NodeState::Done || s == NodeState::Cached; }

// Distinct colours and the spread of grey levels: a uniform (blank) image has 1 and 0.
struct ImageStats {
  int distinct = 0;
  int grey_min = 255, grey_max = 0;
};
ImageStats stats(const QImage& img) {
  ImageStats s;
  QSet<QRgb> colours;
  for (int y = 0; y < img.height(); y += 2) {
    for (int x = 0; x < img.width(); x += 2) {
      const QRgb c = img.pixel(x, y);
      colours.insert(c);
      const int g = qGray(c);
      s.grey_min = std::min(s.grey_min, g);
      s.grey_max = std::max(s.grey_max, g);
    }
  }
  s.distinct = colours.size();
  return s;
}

// field -> threshold -> count, built through the document like the editor does.
void build_test_pipeline(PipelineDocument* doc) {
  ASSERT_EQ(doc->add_node("gui_test.field", {0, 0}), "field");
  ASSERT_EQ(doc->add_node("gui_test.threshold", {260, 0}), "threshold");
  ASSERT_EQ(doc->add_node("gui_test.count", {520, 0}), "count");
  ASSERT_EQ(doc->connect_ports("field", "image", "threshold", "image"), "");
  ASSERT_EQ(doc->connect_ports("threshold", "mask", "count", "mask"), "");
  ASSERT_EQ(doc->set_param("field", "size", ParamValue(std::vector<int64_t>{64, 64, 64})), "");
}

bool wait_run(MainWindow& w, int ms) {
  return QTest::qWaitFor([&] { return !w.runner()->is_running(); }, ms);
}

// Mouse drag in the node view from one scene point to another, with the button held while moving.
void drag(NodeView* view, QPointF from_scene, QPointF to_scene) {
  QWidget* vp = view->viewport();
  const QPoint a = view->mapFromScene(from_scene), b = view->mapFromScene(to_scene);
  QMouseEvent press(QEvent::MouseButtonPress, a, vp->mapToGlobal(a), Qt::LeftButton, Qt::LeftButton, Qt::NoModifier);
  QApplication::sendEvent(vp, &press);
  for (int i = 1; i <= 5; ++i) {
    const QPoint p = a + (b - a) * i / 5;
    QMouseEvent move(QEvent::MouseMove, p, vp->mapToGlobal(p), Qt::NoButton, Qt::LeftButton, Qt::NoModifier);
    QApplication::sendEvent(vp, &move);
  }
  QMouseEvent release(QEvent::MouseButtonRelease, b, vp->mapToGlobal(b), Qt::LeftButton, Qt::NoButton, Qt::NoModifier);
  QApplication::sendEvent(vp, &release);
}

}  // namespace

TEST(Window, RunsPipelineShowsOutputsAndSavesScreenshots) {
  REQUIRE_DISPLAY();
  MainWindow w;
  w.resize(1280, 900);
  w.runner()->set_threads(2);
  build_test_pipeline(w.document());
  w.show();
  ASSERT_TRUE(QTest::qWaitForWindowExposed(&w));
  w.node_view()->fit_all();

  w.run_all();
  EXPECT_TRUE(w.runner()->is_running() || w.runner()->progress() == 1.0);
  ASSERT_TRUE(wait_run(w, 60000));
  QTest::qWait(50);  // queued status updates
  for (const QString& id : w.document()->node_ids()) {
    NodeItem* item = w.scene()->node_item(id);
    ASSERT_NE(item, nullptr);
    EXPECT_TRUE(done(item->status().state)) << id.toStdString() << ": " << to_string(item->status().state);
  }
  EXPECT_EQ(w.progress_bar()->value(), 1000);

  // Image as slices, mask as a voxel surface, both in the 3D view.
  ASSERT_TRUE(w.show_output("field", "image"));
  ASSERT_TRUE(w.show_output("threshold", "mask"));
  EXPECT_EQ(w.view3d()->object_names().size(), 2);
  EXPECT_EQ(w.view3d()->volume_mode("threshold.mask"), VolumeMode::VoxelSurface);
  EXPECT_EQ(w.view3d()->volume_mode("field.image"), VolumeMode::Slices);
  w.view3d()->reset_camera();
  QTest::qWait(100);
  const QString view_png = shot_dir() + "/view3d_slices_voxels.png";
  ASSERT_TRUE(w.view3d()->save_screenshot(view_png));
  const ImageStats s = stats(QImage(view_png));
  EXPECT_GT(s.distinct, 50);
  EXPECT_GT(s.grey_max - s.grey_min, 60);
  w.scene()->select_nodes({"threshold"});
  w.node_view()->fit_all();
  QTest::qWait(50);
  ASSERT_TRUE(w.grab().save(shot_dir() + "/window.png"));

  // Every volume display mode renders something different from the background.
  const QImage blank = [&] {
    w.view3d()->set_object_visible("field.image", false);
    w.view3d()->set_object_visible("threshold.mask", false);
    return w.view3d()->grab_image();
  }();
  EXPECT_FALSE(w.view3d()->object_visible("field.image"));
  w.view3d()->set_object_visible("field.image", true);
  for (VolumeMode m : {VolumeMode::Mip, VolumeMode::IsoSurface, VolumeMode::VolumeRendering, VolumeMode::Slices}) {
    w.view3d()->set_volume_mode("field.image", m);
    const QImage img = w.view3d()->grab_image();
    EXPECT_NE(img, blank) << "mode " << static_cast<int>(m);
    if (m == VolumeMode::IsoSurface) img.save(shot_dir() + "/view3d_iso.png");
    if (m == VolumeMode::Mip) img.save(shot_dir() + "/view3d_mip.png");
  }

  // The table output goes to the table dock; its value equals a count over the mask.
  ASSERT_TRUE(w.show_output("count", "table"));
  ASSERT_EQ(w.table_view()->rowCount(), 1);
  auto mask = std::dynamic_pointer_cast<const VolumeU8>(w.runner()->output("threshold", "mask"));
  ASSERT_NE(mask, nullptr);
  int64_t n = 0;
  for (uint8_t v : *mask) n += v;
  EXPECT_GT(n, 0);
  EXPECT_EQ(w.table_view()->item(0, 0)->text().toLongLong(), n);
}

TEST(Window, GraphsAsTubesColouredByAttribute) {
  REQUIRE_DISPLAY();
  MainWindow w;
  w.resize(1280, 900);
  ASSERT_EQ(w.document()->add_node("gui_test.graph", {0, 0}), "graph");
  w.show();
  ASSERT_TRUE(QTest::qWaitForWindowExposed(&w));
  // Clicking a port whose output is not computed runs what it needs, then shows it.
  EXPECT_FALSE(w.show_output("graph", "graph"));
  ASSERT_TRUE(wait_run(w, 30000));
  QTest::qWait(50);
  ASSERT_TRUE(w.view3d()->has_object("graph.graph"));
  auto bar_visible = [&] {
    vtkPropCollection* props = w.view3d()->renderer()->GetViewProps();
    props->InitTraversal();
    while (vtkProp* p = props->GetNextProp()) {
      if (p->IsA("vtkScalarBarActor")) return p->GetVisibility() != 0;
    }
    return false;
  };
  EXPECT_TRUE(bar_visible());  // tubes coloured by radius
  w.view3d()->reset_camera();
  const QImage tubes = w.view3d()->grab_image();
  const ImageStats s = stats(tubes);
  EXPECT_GT(s.distinct, 50);
  EXPECT_GT(s.grey_max - s.grey_min, 60);
  tubes.save(shot_dir() + "/view3d_graph_tubes.png");
  w.view3d()->set_graph_color_by("graph.graph", "length");
  EXPECT_TRUE(bar_visible());
  w.view3d()->set_graph_mode("graph.graph", GraphMode::Lines);
  w.view3d()->set_graph_color_by("graph.graph", "");
  EXPECT_FALSE(bar_visible());
  const QImage lines = w.view3d()->grab_image();
  EXPECT_NE(lines, tubes);
  EXPECT_GT(stats(lines).distinct, 2);
}

TEST(Window, MeshesColouredByManifoldClass) {
  REQUIRE_DISPLAY();
  MainWindow w;
  w.resize(1280, 900);
  ASSERT_EQ(w.document()->add_node("gui_test.mesh", {0, 0}), "mesh");
  w.show();
  ASSERT_TRUE(QTest::qWaitForWindowExposed(&w));
  EXPECT_FALSE(w.show_output("mesh", "mesh"));
  ASSERT_TRUE(wait_run(w, 30000));
  QTest::qWait(50);
  ASSERT_TRUE(w.view3d()->has_object("mesh.mesh"));
  bool bar = false;
  vtkPropCollection* props = w.view3d()->renderer()->GetViewProps();
  props->InitTraversal();
  while (vtkProp* p = props->GetNextProp())
    if (p->IsA("vtkScalarBarActor")) bar = p->GetVisibility() != 0;
  EXPECT_TRUE(bar);  // coloured by the triangles' manifold class
  w.view3d()->reset_camera();
  QTest::qWait(50);
  const QImage img = w.view3d()->grab_image();
  const ImageStats s = stats(img);
  EXPECT_GT(s.distinct, 30);
  EXPECT_GT(s.grey_max - s.grey_min, 60);
  img.save(shot_dir() + "/view3d_mesh.png");
}

// Issue 18: after a run the final geometry is shown without a click (as Amira does), unless the user
// chose what to show.
TEST(Window, RunShowsTheFinalGeometryWithoutAClick) {
  REQUIRE_DISPLAY();
  {
    MainWindow w;
    w.resize(1280, 900);
    w.runner()->set_threads(2);
    build_test_pipeline(w.document());  // volumes and a table only
    w.show();
    ASSERT_TRUE(QTest::qWaitForWindowExposed(&w));
    w.run_all();
    ASSERT_TRUE(wait_run(w, 60000));
    QTest::qWait(50);
    // No mesh or graph: the sink-most volume (the count's table is no geometry).
    EXPECT_EQ(w.view3d()->object_names(), QStringList{"threshold.mask"});
  }
  {
    MainWindow w;
    w.resize(1280, 900);
    w.runner()->set_threads(2);
    build_test_pipeline(w.document());
    ASSERT_EQ(w.document()->add_node("gui_test.graph", {0, 300}), "graph");
    ASSERT_EQ(w.document()->add_node("gui_test.mesh", {0, 600}), "mesh");
    w.show();
    ASSERT_TRUE(QTest::qWaitForWindowExposed(&w));
    EXPECT_TRUE(w.view3d()->object_names().isEmpty());
    w.run_all();
    ASSERT_TRUE(wait_run(w, 60000));
    QTest::qWait(50);
    QStringList names = w.view3d()->object_names();
    names.sort();
    EXPECT_EQ(names, (QStringList{"graph.graph", "mesh.mesh"}));
    w.view3d()->reset_camera();
    QTest::qWait(50);
    const ImageStats st = stats(w.view3d()->grab_image());
    EXPECT_GT(st.distinct, 50);
    // A re-run keeps what is shown (and does not add the volume).
    ASSERT_EQ(w.document()->set_param("field", "size", ParamValue(std::vector<int64_t>{48, 48, 48})), "");
    w.run_all();
    ASSERT_TRUE(wait_run(w, 60000));
    QTest::qWait(50);
    names = w.view3d()->object_names();
    names.sort();
    EXPECT_EQ(names, (QStringList{"graph.graph", "mesh.mesh"}));
  }
  {
    // The user chose: a port clicked before the run is all the view shows.
    MainWindow w;
    w.resize(1280, 900);
    w.runner()->set_threads(2);
    build_test_pipeline(w.document());
    ASSERT_EQ(w.document()->add_node("gui_test.graph", {0, 300}), "graph");
    w.show();
    ASSERT_TRUE(QTest::qWaitForWindowExposed(&w));
    EXPECT_FALSE(w.show_output("field", "image"));  // runs what it needs, then shows it
    ASSERT_TRUE(wait_run(w, 60000));
    QTest::qWait(50);
    EXPECT_EQ(w.view3d()->object_names(), QStringList{"field.image"});
    w.view3d()->clear();
    w.run_all();
    ASSERT_TRUE(wait_run(w, 60000));
    QTest::qWait(50);
    EXPECT_TRUE(w.view3d()->object_names().isEmpty());
  }
}

// Issue 18: the 16-node vessel pipeline (a long chain) opens laid out in rows, fitted at a zoom where
// node names stay legible in a 1280x800 window, starting with its first node in view.
TEST(Window, LongChainsWrapIntoRowsAtALegibleZoom) {
  REQUIRE_DISPLAY();
  const QString file = QString(SKEL_SOURCE_DIR) + "/pipelines/vessel_network.yaml";
  MainWindow w;
  w.resize(1280, 800);
  w.show();
  ASSERT_TRUE(QTest::qWaitForWindowExposed(&w));
  ASSERT_TRUE(w.open_file(file));
  QTest::qWait(100);
  ASSERT_GE(w.document()->node_ids().size(), 15);
  QRectF box;  // the nodes
  for (const QString& id : w.document()->node_ids()) box = box.united(w.scene()->node_item(id)->sceneBoundingRect());
  // No two nodes overlap.
  const QStringList ids = w.document()->node_ids();
  for (int i = 0; i < ids.size(); ++i)
    for (int j = i + 1; j < ids.size(); ++j)
      EXPECT_FALSE(w.scene()->node_item(ids[i])->sceneBoundingRect().adjusted(4, 4, -4, -4).intersects(
          w.scene()->node_item(ids[j])->sceneBoundingRect().adjusted(4, 4, -4, -4)))
          << ids[i].toStdString() << " overlaps " << ids[j].toStdString();
  // One row would be ~10 columns of 220 by one node: aspect ~15. In rows it is closer to the view's.
  EXPECT_LT(box.width() / box.height(), 2.5) << box.width() << "x" << box.height();
  EXPECT_GE(w.document()->layout_columns(), 2);
  const double zoom = w.node_view()->transform().m11();
  EXPECT_GE(zoom, NodeView::kLegibleZoom - 1e-9);
  EXPECT_LE(zoom, 1.0 + 1e-9);
  // Node names are drawn at 10 pt: on screen at least 9 pt.
  EXPECT_GE(10.0 * zoom, 9.0 - 1e-9);
  // The rows fit the editor's width (no sideways scrolling), and the chain's start is in view.
  const QRect vp = w.node_view()->viewport()->rect();
  EXPECT_LE(box.width() * zoom, vp.width() + 1.0) << box.width() * zoom << " > " << vp.width();
  NodeItem* first = w.scene()->node_item("phantom");
  ASSERT_NE(first, nullptr);
  const QRect first_on_screen = w.node_view()->mapFromScene(first->sceneBoundingRect().adjusted(4, 4, -4, -4)).boundingRect();
  EXPECT_TRUE(vp.contains(first_on_screen)) << first_on_screen.x() << "," << first_on_screen.y();
  // Its successor, in the next column, is in view too (with its output ports).
  const QRect second =
      w.node_view()->mapFromScene(w.scene()->node_item("smooth")->sceneBoundingRect().adjusted(4, 4, -4, -4)).boundingRect();
  EXPECT_TRUE(vp.contains(second)) << second.x() << "," << second.y() << " " << second.width() << "x" << second.height();
  ASSERT_TRUE(w.node_view()->grab().save(shot_dir() + "/node_editor_vessels.png"));
  ASSERT_TRUE(w.grab().save(shot_dir() + "/window_vessels.png"));
}

TEST(Window, EditorConnectsRefusesWithReasonAndUndoes) {
  REQUIRE_DISPLAY();
  MainWindow w;
  PipelineDocument* doc = w.document();
  ASSERT_EQ(doc->add_node("gui_test.field", {0, 0}), "field");
  ASSERT_EQ(doc->add_node("gui_test.threshold", {300, 0}), "threshold");
  ASSERT_EQ(doc->add_node("gui_test.count", {600, 0}), "count");
  w.show();
  ASSERT_TRUE(QTest::qWaitForWindowExposed(&w));
  w.node_view()->fit_all();
  QTest::qWait(20);
  NodeScene* scene = w.scene();
  auto anchor = [&](const char* node, const char* port, bool output) {
    NodeItem* n = scene->node_item(node);
    PortItem* p = output ? n->output(port) : n->input(port);
    return p->anchor();
  };

  // field.image -> threshold.image: accepted.
  drag(w.node_view(), anchor("field", "image", true), anchor("threshold", "image", false));
  ASSERT_EQ(doc->pipeline().find("threshold")->inputs.count("image"), 1u);
  EXPECT_EQ(doc->pipeline().find("threshold")->inputs.at("image").str(), "field.image");

  // field.image (float32) -> count.mask (uint8): refused, the engine's reason is shown.
  drag(w.node_view(), anchor("field", "image", true), anchor("count", "mask", false));
  EXPECT_TRUE(doc->pipeline().find("count")->inputs.empty());
  EXPECT_TRUE(w.log_text().contains("Connection refused")) << w.log_text().toStdString();
  EXPECT_TRUE(w.log_text().contains("volume.f32")) << w.log_text().toStdString();

  // The actions bound to Ctrl+Z / Ctrl+Shift+Z undo and redo the connection. (Xvfb has no window
  // manager to activate the window, so the actions are triggered rather than the keys typed.)
  auto action = [&](const QKeySequence& key) -> QAction* {
    for (QAction* a : w.findChildren<QAction*>()) {
      if (a->shortcuts().contains(key)) return a;
    }
    return nullptr;
  };
  QAction* undo = action(QKeySequence("Ctrl+Z"));
  QAction* redo = action(QKeySequence("Ctrl+Shift+Z"));
  ASSERT_NE(undo, nullptr);
  ASSERT_NE(redo, nullptr);
  undo->trigger();
  EXPECT_TRUE(doc->pipeline().find("threshold")->inputs.empty());
  redo->trigger();
  EXPECT_EQ(doc->pipeline().find("threshold")->inputs.count("image"), 1u);

  // Moving a node by dragging its header is one undoable command.
  const QPointF before = doc->position("count");
  drag(w.node_view(), before + QPointF(60, 10), before + QPointF(60, 110));
  EXPECT_NEAR(doc->position("count").y(), before.y() + 100, 2.0);
  doc->undo_stack()->undo();
  EXPECT_EQ(doc->position("count"), before);

  // Select + delete, then undo.
  scene->select_nodes({"threshold"});
  scene->delete_selection();
  EXPECT_FALSE(doc->has_node("threshold"));
  doc->undo_stack()->undo();
  EXPECT_TRUE(doc->has_node("threshold"));
  EXPECT_NE(scene->node_item("threshold"), nullptr);
  EXPECT_EQ(doc->pipeline().find("threshold")->inputs.at("image").str(), "field.image");
}

TEST(Window, PaletteDropAndPropertiesPanel) {
  REQUIRE_DISPLAY();
  MainWindow w;
  w.runner()->set_threads(2);
  w.show();
  ASSERT_TRUE(QTest::qWaitForWindowExposed(&w));

  // Search filters the palette.
  w.palette()->set_filter("thresh");
  EXPECT_TRUE(w.palette()->visible_modules().contains("gui_test.threshold"));
  EXPECT_FALSE(w.palette()->visible_modules().contains("gui_test.field"));
  w.palette()->set_filter("");

  // Dropping a palette item onto the canvas adds a node there.
  QMimeData mime;
  mime.setData(kModuleMime, "gui_test.field");
  QWidget* vp = w.node_view()->viewport();
  const QPoint at = vp->rect().center();
  QDragEnterEvent enter(at, Qt::CopyAction, &mime, Qt::LeftButton, Qt::NoModifier);
  QApplication::sendEvent(vp, &enter);
  QDropEvent drop(at, Qt::CopyAction, &mime, Qt::LeftButton, Qt::NoModifier);
  QApplication::sendEvent(vp, &drop);
  ASSERT_TRUE(w.document()->has_node("field"));
  EXPECT_LT(QLineF(w.document()->position("field"), w.node_view()->mapToScene(at)).length(), 2.0);

  PipelineDocument* doc = w.document();
  const QString t = doc->add_node("gui_test.threshold", {300, 0});
  ASSERT_EQ(doc->add_node("gui_test.count", {600, 0}), "count");
  ASSERT_EQ(doc->connect_ports("field", "image", t, "image"), "");
  ASSERT_EQ(doc->connect_ports(t, "mask", "count", "mask"), "");
  ASSERT_EQ(doc->set_param("field", "size", ParamValue(std::vector<int64_t>{48, 48, 48})), "");
  w.run_all();
  ASSERT_TRUE(wait_run(w, 60000));
  const int64_t runs = w.runner()->executor().modules_run();

  // Selecting a node shows its parameters; the spin box refuses values out of the spec's range.
  w.scene()->select_nodes({t});
  ASSERT_EQ(w.properties()->node(), t);
  auto* level = qobject_cast<QDoubleSpinBox*>(w.properties()->editor("level"));
  ASSERT_NE(level, nullptr);
  EXPECT_EQ(level->maximum(), 1.0);
  EXPECT_EQ(level->minimum(), 0.0);
  ASSERT_TRUE(w.show_output(t, "mask"));
  const DataPtr old_mask = w.view3d()->object_data("threshold.mask");
  w.view3d()->set_volume_mode("threshold.mask", VolumeMode::IsoSurface);
  level->setValue(1.5);  // clamped at entry
  EXPECT_EQ(std::get<double>(w.document()->pipeline().find("threshold")->params.at("level")), 1.0);
  level->setValue(0.3);
  EXPECT_EQ(std::get<double>(w.document()->pipeline().find("threshold")->params.at("level")), 0.3);
  QTest::qWait(20);
  EXPECT_EQ(w.scene()->node_item(t)->status().state, NodeState::Stale);
  EXPECT_EQ(w.scene()->node_item("count")->status().state, NodeState::Stale);
  EXPECT_TRUE(done(w.scene()->node_item("field")->status().state));

  // Re-running recomputes only the changed node and what depends on it; a shown output follows.
  w.run_all();
  ASSERT_TRUE(wait_run(w, 60000));
  QTest::qWait(20);
  EXPECT_EQ(w.runner()->executor().modules_run(), runs + 2);
  EXPECT_NE(w.view3d()->object_data("threshold.mask"), old_mask);
  EXPECT_EQ(w.view3d()->object_data("threshold.mask"), w.runner()->output(t, "mask"));
  EXPECT_EQ(w.view3d()->volume_mode("threshold.mask"), VolumeMode::IsoSurface);
  for (const QString& id : w.document()->node_ids()) {
    EXPECT_TRUE(done(w.scene()->node_item(id)->status().state)) << id.toStdString();
  }

  // Undo of the parameter edit is reflected in the panel.
  w.document()->undo_stack()->undo();
  QTest::qWait(20);
  level = qobject_cast<QDoubleSpinBox*>(w.properties()->editor("level"));
  ASSERT_NE(level, nullptr);
  EXPECT_EQ(level->value(), 1.0);
}

// A parameter in the input's unit (units::length) shows the unit of the data once a run has made
// it: a phantom in mm gives the Gaussian's sigma the label "mm".
TEST(Window, LengthParametersShowTheUnitOfTheData) {
  REQUIRE_DISPLAY();
  MainWindow w;
  w.runner()->set_threads(2);
  w.show();
  ASSERT_TRUE(QTest::qWaitForWindowExposed(&w));
  PipelineDocument* doc = w.document();
  const QString phantom = doc->add_node("synthetic.network", {0, 0});
  const QString smooth = doc->add_node("segmentation.gaussian", {300, 0});
  ASSERT_EQ(doc->connect_ports(phantom, "image", smooth, "image"), "");
  ASSERT_EQ(doc->set_param(phantom, "size", ParamValue(std::vector<int64_t>{24, 24, 24})), "");
  ASSERT_EQ(doc->set_param(phantom, "unit", ParamValue(std::string("mm"))), "");
  const auto labels = [&] {
    QStringList l;
    for (const QLabel* q : w.properties()->editor("sigma")->findChildren<QLabel*>()) l << q->text();
    return l;
  };
  w.scene()->select_nodes({smooth});
  ASSERT_EQ(w.properties()->node(), smooth);
  EXPECT_TRUE(labels().contains(QString::fromUtf8(skel::units::length))) << labels().join("|").toStdString();
  w.run_all();
  ASSERT_TRUE(wait_run(w, 60000));
  QTest::qWait(20);
  EXPECT_TRUE(labels().contains("mm")) << labels().join("|").toStdString();
}

TEST(Window, ProgressIsDrawnWhileTheUiStaysResponsiveAndCancelStops) {
  REQUIRE_DISPLAY();
  MainWindow w;
  ASSERT_EQ(w.document()->add_node("gui_test.slow", {0, 0}), "slow");
  ASSERT_EQ(w.document()->set_param("slow", "seconds", ParamValue(60.0)), "");
  w.show();
  ASSERT_TRUE(QTest::qWaitForWindowExposed(&w));
  // Count turns of the UI event loop while the pipeline runs.
  int ticks = 0;
  QTimer timer;
  QObject::connect(&timer, &QTimer::timeout, [&] { ++ticks; });
  timer.start(10);
  w.run_all();
  NodeItem* node = w.scene()->node_item("slow");
  ASSERT_TRUE(QTest::qWaitFor(
      [&] { return node->status().state == NodeState::Running && node->status().progress > 0.005; }, 20000));
  EXPECT_GT(w.progress_bar()->value(), 0);
  EXPECT_LT(w.progress_bar()->value(), 1000);
  QTest::qWait(300);
  EXPECT_GT(ticks, 10);  // the event loop kept running during the computation
  EXPECT_TRUE(w.runner()->is_running());

  QElapsedTimer clock;
  clock.start();
  w.cancel_run();
  ASSERT_TRUE(wait_run(w, 10000));
  EXPECT_LT(clock.elapsed(), 3000);
  QTest::qWait(50);
  EXPECT_EQ(node->status().state, NodeState::Cancelled);
  EXPECT_TRUE(w.log_text().contains("cancelled")) << w.log_text().toStdString();
  EXPECT_EQ(w.runner()->output("slow", "mask"), nullptr);
}

TEST(Window, FilesRoundTripAndRecentList) {
  REQUIRE_DISPLAY();
  const QString dir = shot_dir();
  const QString path = dir + "/roundtrip.yaml";
  {
    MainWindow w;
    build_test_pipeline(w.document());
    w.document()->move_nodes({{"count", QPointF(555, 77)}});
    EXPECT_TRUE(w.isWindowModified() || w.document()->is_modified());
    ASSERT_TRUE(w.save_file(path));
    EXPECT_FALSE(w.document()->is_modified());
    EXPECT_EQ(w.recent_files().value(0), QFileInfo(path).absoluteFilePath());
  }
  MainWindow w;
  ASSERT_TRUE(w.open_file(path));
  EXPECT_EQ(w.document()->position("count"), QPointF(555, 77));
  EXPECT_EQ(w.document()->node_ids(), (QStringList{"field", "threshold", "count"}));
  EXPECT_FALSE(w.open_file(dir + "/does_not_exist.yaml"));
  EXPECT_TRUE(w.log_text().contains("does_not_exist.yaml"));
  EXPECT_TRUE(w.maybe_save());  // nothing to save: no question
  // Unsaved changes: the question offers Save / Discard / Cancel.
  w.document()->remove_nodes({"count"});
  EXPECT_TRUE(w.isWindowModified());
  auto answer_with = [](QMessageBox::StandardButton button) {
    QTimer::singleShot(200, [button] {
      auto* box = qobject_cast<QMessageBox*>(QApplication::activeModalWidget());
      ASSERT_NE(box, nullptr);
      box->button(button)->click();
    });
  };
  answer_with(QMessageBox::Cancel);
  EXPECT_FALSE(w.maybe_save());
  answer_with(QMessageBox::Discard);
  EXPECT_TRUE(w.maybe_save());
  answer_with(QMessageBox::Save);
  EXPECT_TRUE(w.maybe_save());
  EXPECT_FALSE(w.document()->is_modified());
  EXPECT_EQ(Pipeline::load_file(path.toStdString()).nodes().size(), 2u);
}

// The rods phantom, its Euclidean distance and a thinning node `thin_id` (module `thinning`) reading
// both, as the 3D-view tests start from.
static void add_rods_distance_thinning(PipelineDocument* doc, int64_t n, const char* thinning, const char* thin_id) {
  ASSERT_EQ(doc->add_node("synthetic.network", {0, 0}), "network");
  ASSERT_EQ(doc->add_node("distance.euclidean", {240, 120}), "euclidean");
  ASSERT_EQ(doc->add_node(thinning, {480, 0}), thin_id);
  ASSERT_EQ(doc->set_param("network", "size", ParamValue(std::vector<int64_t>{n, n, n})), "");
  ASSERT_EQ(doc->set_param("network", "radius", ParamValue(3.0)), "");
  ASSERT_EQ(doc->set_param("network", "period", ParamValue(20.0)), "");
  ASSERT_EQ(doc->connect_ports("network", "mask", "euclidean", "mask"), "");
  ASSERT_EQ(doc->connect_ports("network", "mask", thin_id, "mask"), "");
  ASSERT_EQ(doc->connect_ports("euclidean", "distance", thin_id, "priority"), "");
}

TEST(Window, SkeletonPipelineFromRealModules) {
  REQUIRE_DISPLAY();
  for (const char* m : {"synthetic.network", "distance.euclidean", "thinning.doht", "geometry.skeleton_to_graph"}) {
    if (!Registry::instance().find(m)) GTEST_SKIP() << m << " is not registered in this build";
  }
  MainWindow w;
  w.resize(1280, 900);
  w.runner()->set_threads(2);
  PipelineDocument* doc = w.document();
  ASSERT_NO_FATAL_FAILURE(add_rods_distance_thinning(doc, 64, "thinning.doht", "doht"));
  ASSERT_EQ(doc->add_node("geometry.skeleton_to_graph", {720, 60}), "skeleton_to_graph");
  ASSERT_EQ(doc->connect_ports("doht", "skeleton", "skeleton_to_graph", "skeleton"), "");
  ASSERT_EQ(doc->connect_ports("euclidean", "distance", "skeleton_to_graph", "distance"), "");
  EXPECT_TRUE(validate(doc->pipeline()).empty());
  // Stages that run block by block under a memory budget carry a badge and say so in the tooltip.
  EXPECT_TRUE(w.scene()->node_item("euclidean")->blockwise());
  EXPECT_TRUE(w.scene()->node_item("doht")->toolTip().contains("block by block"));
  EXPECT_FALSE(w.scene()->node_item("network")->blockwise());
  EXPECT_FALSE(w.scene()->node_item("network")->toolTip().contains("block by block"));
  // The YAML the GUI saves is the YAML `skelflow run` reads.
  const QString yaml = shot_dir() + "/skeleton_pipeline.yaml";
  ASSERT_TRUE(w.save_file(yaml));
  EXPECT_TRUE(Pipeline::load_file(yaml.toStdString()) == doc->pipeline());

  w.show();
  ASSERT_TRUE(QTest::qWaitForWindowExposed(&w));
  w.run_all();
  ASSERT_TRUE(wait_run(w, 120000));
  QTest::qWait(50);
  for (const QString& id : doc->node_ids()) {
    EXPECT_TRUE(done(w.scene()->node_item(id)->status().state)) << id.toStdString() << ": " << w.runner()->status(id).message;
  }
  ASSERT_TRUE(w.show_output("network", "image"));
  ASSERT_TRUE(w.show_output("skeleton_to_graph", "graph"));
  w.scene()->select_nodes({"doht"});
  w.node_view()->fit_all();
  w.view3d()->reset_camera();
  QTest::qWait(100);
  const QString png = shot_dir() + "/skeleton_view3d.png";
  ASSERT_TRUE(w.view3d()->save_screenshot(png));
  const ImageStats s = stats(QImage(png));
  EXPECT_GT(s.distinct, 50);
  EXPECT_GT(s.grey_max - s.grey_min, 60);
  ASSERT_TRUE(w.grab().save(shot_dir() + "/skeleton_window.png"));
  // The skeleton as a voxel surface instead of the image slices.
  w.view3d()->set_object_visible("network.image", false);
  ASSERT_TRUE(w.show_output("doht", "skeleton"));
  EXPECT_EQ(w.view3d()->volume_mode("doht.skeleton"), VolumeMode::VoxelSurface);
  w.view3d()->set_object_visible("skeleton_to_graph.graph", false);
  const QImage skel = w.view3d()->grab_image();
  EXPECT_GT(stats(skel).distinct, 20);
  skel.save(shot_dir() + "/skeleton_voxels.png");
}

TEST(Window, GridCellSkeletonIsShownAsItsSimpleGeometry) {
  REQUIRE_DISPLAY();
  for (const char* m : {"synthetic.network", "distance.euclidean", "thinning.grid_cell"}) {
    if (!Registry::instance().find(m)) GTEST_SKIP() << m << " is not registered in this build";
  }
  MainWindow w;
  w.resize(1280, 900);
  w.runner()->set_threads(2);
  PipelineDocument* doc = w.document();
  ASSERT_NO_FATAL_FAILURE(add_rods_distance_thinning(doc, 48, "thinning.grid_cell", "grid_cell"));
  w.show();
  ASSERT_TRUE(QTest::qWaitForWindowExposed(&w));
  w.run_all();
  ASSERT_TRUE(wait_run(w, 120000));
  QTest::qWait(50);
  // The cells are not a volume, graph or mesh: the view shows them as the simple geometry of
  // geometry.cells_to_mesh (lines for the 1-cells of the rods), which has pixels to see.
  ASSERT_TRUE(w.show_output("grid_cell", "skeleton"));
  EXPECT_TRUE(w.view3d()->has_object("grid_cell.skeleton"));
  w.view3d()->reset_camera();
  QTest::qWait(100);
  const QString png = shot_dir() + "/grid_cell_skeleton.png";
  ASSERT_TRUE(w.view3d()->save_screenshot(png));
  EXPECT_GT(stats(QImage(png)).distinct, 20);
}

TEST(Window, DemoPipeline) {
  REQUIRE_DISPLAY();
  const QString demo = QString(SKEL_SOURCE_DIR) + "/pipelines/demo.yaml";
  if (!QFileInfo::exists(demo)) GTEST_SKIP() << "pipelines/demo.yaml does not exist yet";
  MainWindow w;
  w.runner()->set_threads(2);
  // The demo writes files: keep them in the build folder, not next to the pipeline in the sources.
  const QString out = shot_dir() + "/demo_outputs";
  w.runner()->set_output_dir(out);
  w.resize(1280, 900);
  ASSERT_TRUE(w.open_file(demo));
  const auto problems = validate(w.document()->pipeline());
  if (!problems.empty()) GTEST_SKIP() << "demo.yaml does not validate here: " << problems.front().format();
  // Keep the widget test small: shrink every `size` parameter of a source to 64^3.
  for (const QString& id : w.document()->node_ids()) {
    const ModuleSpec* spec = w.document()->spec(id);
    const ParamSpec* size = spec ? spec->find_param("size") : nullptr;
    if (size && size->type == ParamType::IntList) {
      (void)w.document()->set_param(id, "size", ParamValue(std::vector<int64_t>{64, 64, 64}));
    }
  }
  w.show();
  ASSERT_TRUE(QTest::qWaitForWindowExposed(&w));
  w.node_view()->fit_all();
  w.run_all();
  ASSERT_TRUE(wait_run(w, 240000));
  QTest::qWait(50);
  for (const QString& id : w.document()->node_ids()) {
    EXPECT_TRUE(done(w.scene()->node_item(id)->status().state))
        << id.toStdString() << ": " << w.runner()->status(id).message;
  }
  // The demo's image and skeleton when it has them; otherwise volume or graph outputs of the last
  // nodes, at most three.
  int shown = 0;
  if (w.runner()->output("phantom", "image") && w.runner()->output("skeleton", "skeleton")) {
    shown += w.show_output("phantom", "image") ? 1 : 0;
    shown += w.show_output("skeleton", "skeleton") ? 1 : 0;
  } else {
    QStringList ids = w.document()->node_ids();
    std::reverse(ids.begin(), ids.end());
    for (const QString& id : ids) {
      const ModuleSpec* spec = w.document()->spec(id);
      for (const auto& out : spec->outputs()) {
        DataPtr d = w.runner()->output(id, QString::fromStdString(out.name));
        if (!d || shown >= 3) continue;
        if (d->type_id() == type_ids::graph || d->type_id().rfind("volume.", 0) == 0) {
          shown += w.show_output(id, QString::fromStdString(out.name)) ? 1 : 0;
        }
      }
    }
  }
  ASSERT_GT(shown, 0);
  w.view3d()->reset_camera();
  QTest::qWait(100);
  const QString png = shot_dir() + "/demo_view3d.png";
  ASSERT_TRUE(w.view3d()->save_screenshot(png));
  const ImageStats s = stats(QImage(png));
  EXPECT_GT(s.distinct, 50);
  EXPECT_GT(s.grey_max - s.grey_min, 60);
  ASSERT_TRUE(w.grab().save(shot_dir() + "/demo_window.png"));
  EXPECT_FALSE(QFileInfo::exists(QString(SKEL_SOURCE_DIR) + "/pipelines/demo"));
}

// A plugin loaded before the window is built (as gui/main.cpp does) puts its modules in the
// palette like built-in ones. Last in this file: the module stays registered for the process.
TEST(Window, PluginModulesJoinThePalette) {
  REQUIRE_DISPLAY();
  ASSERT_EQ(skel::load_plugin(SKEL_BINARY_DIR "/tests/plugins/good/invert_plugin.so"), "");
  MainWindow w;
  w.show();
  ASSERT_TRUE(QTest::qWaitForWindowExposed(&w));
  w.palette()->set_filter("invert");
  EXPECT_EQ(w.palette()->visible_modules(), QStringList{"plugin_test.invert"});
}

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  const char* display = std::getenv("DISPLAY");
  g_have_display = display && *display;
  if (!g_have_display) return RUN_ALL_TESTS();  // every test skips with the reason
  // VTK renders through OpenGL: the offscreen platform cannot, xcb (on Xvfb + Mesa) can.
  setenv("QT_QPA_PLATFORM", "xcb", 0);
  QSurfaceFormat::setDefaultFormat(QVTKOpenGLNativeWidget::defaultFormat());
  QStandardPaths::setTestModeEnabled(true);  // recent files go to a test settings file
  QApplication app(argc, argv);
  QApplication::setOrganizationName("skelflow-test");
  QApplication::setApplicationName("gui_window_test");
  return RUN_ALL_TESTS();
}
