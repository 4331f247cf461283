// The landmark mode of skelflow-gui (issue 9) under a virtual X server: open a small pipeline with a
// phantom image, run it, show the image as three slices, enter landmark mode, place four pairs with
// mouse clicks (each point must be what the picker finds under the cursor: on one of the slice
// planes, projected back onto the clicked pixel), check the residual table against an independent
// fit, drag a landmark onto another slice position, undo/redo with the keys of the 3D view, save
// (.landmarkAscii + io.read_landmarks/registration.landmarks nodes whose run reproduces the RMS),
// clear and reload, and place a point on the iso-surface (image value = iso value there).
//
// Screenshots go to <build>/gui_screenshots; with SKELFLOW_UPDATE_DOC_IMAGES=1 also to docs/images.
#include <gtest/gtest.h>

#include <QAction>
#include <QApplication>
#include <QDir>
#include <QDockWidget>
#include <QFile>
#include <QFileInfo>
#include <QMenuBar>
#include <QSignalSpy>
#include <QSplitter>
#include <QStandardPaths>
#include <QSurfaceFormat>
#include <QTableView>
#include <QTemporaryDir>
#include <QTest>

#include <QVTKOpenGLNativeWidget.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>

#include "io/landmark_io.hpp"
#include "landmark_session.hpp"
#include "main_window.hpp"
#include "modes/landmark_mode.hpp"
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

bool run_and_wait(MainWindow& w, int ms, const QStringList& targets = {}) {
  if (targets.isEmpty()) w.run_all();
  else w.runner()->start(targets);
  const bool ok = QTest::qWaitFor([&] { return !w.runner()->is_running(); }, ms);
  QTest::qWait(50);  // queued status updates
  return ok;
}

QString write_pipeline(const QString& dir) {
  const QString path = QDir(dir).filePath("landmarks_pipeline.yaml");
  QFile f(path);
  if (!f.open(QIODevice::WriteOnly)) return {};
  f.write("skelflow: 1\n"
          "nodes:\n"
          "  phantom: {module: synthetic.network, params: {shape: rods, size: [40, 40, 40], period: 16, "
          "spacing: [1.0, 1.25, 1.5]}}\n");
  return path;
}

double dist(const Vec3& a, const Vec3& b) { return std::hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]); }

// Trilinear image value at a physical position (clamped to the grid).
double trilinear(const VolumeF32& v, const Vec3& p) {
  const Grid& g = v.grid();
  int64_t i0[3];
  double f[3];
  for (int k = 0; k < 3; ++k) {
    const double x = std::clamp((p[k] - g.origin[k]) / g.spacing[k], 0.0, double(g.dims[k] - 1));
    i0[k] = std::min<int64_t>(static_cast<int64_t>(std::floor(x)), g.dims[k] - 2);
    f[k] = x - double(i0[k]);
  }
  double value = 0;
  for (int c = 0; c < 8; ++c) {
    const int dx = c & 1, dy = (c >> 1) & 1, dz = (c >> 2) & 1;
    const double w = (dx ? f[0] : 1 - f[0]) * (dy ? f[1] : 1 - f[1]) * (dz ? f[2] : 1 - f[2]);
    value += w * v(i0[0] + dx, i0[1] + dy, i0[2] + dz);
  }
  return value;
}

}  // namespace

TEST(LandmarkMode, PlaceDragUndoSaveReload) {
  REQUIRE_DISPLAY();
  QTemporaryDir tmp;
  ASSERT_TRUE(tmp.isValid());
  const QString pipeline = write_pipeline(tmp.path());
  ASSERT_FALSE(pipeline.isEmpty());

  MainWindow w;
  w.resize(1680, 1000);
  w.runner()->set_threads(2);
  ASSERT_TRUE(w.open_file(pipeline));
  w.show();
  ASSERT_TRUE(QTest::qWaitForWindowExposed(&w));
  ASSERT_TRUE(run_and_wait(w, 120000));
  // The run showed its final geometry by itself; this test picks on the image's slices alone.
  w.view3d()->clear();
  ASSERT_TRUE(w.show_output("phantom", "image")) << w.log_text().toStdString();
  ASSERT_EQ(w.view3d()->volume_mode("phantom.image"), VolumeMode::Slices);
  auto image = std::dynamic_pointer_cast<const VolumeF32>(w.runner()->output("phantom", "image"));
  ASSERT_NE(image, nullptr);
  const Grid& grid = image->grid();
  // The view shows the middle slice of each axis.
  Vec3 plane{};
  for (int k = 0; k < 3; ++k) plane[k] = grid.origin[k] + double((grid.dims[k] - 1) / 2) * grid.spacing[k];

  // Enter landmark mode through the Edit menu's action.
  QAction* enter = nullptr;
  for (QAction* a : w.menuBar()->actions()) {
    if (!a->menu()) continue;
    for (QAction* b : a->menu()->actions()) {
      if (b->text().contains("Landmarks")) enter = b;
    }
  }
  ASSERT_NE(enter, nullptr);
  EXPECT_EQ(enter->shortcut(), QKeySequence("Ctrl+L"));
  enter->trigger();
  // More room for the 3D view than for the node editor (one node here).
  if (auto* split = qobject_cast<QSplitter*>(w.centralWidget())) split->setSizes({250, 1000});
  LandmarkMode* lm = w.landmark_mode();
  ASSERT_TRUE(lm->active());
  ASSERT_NE(lm->dock(), nullptr);
  ASSERT_NE(lm->table(), nullptr);
  LandmarkSession* s = lm->session();
  QWidget* vtk = lm->vtk_widget();
  ASSERT_NE(vtk, nullptr);
  w.view3d()->reset_camera();
  QTest::qWait(100);

  // Screen positions where the picker hits a slice, spread around the view's centre.
  const QPoint c(vtk->width() / 2, vtk->height() / 2);
  const QPoint wanted[] = {{-70, -60}, {-60, -50}, {70, -60}, {60, -45}, {-20, 70}, {-30, 60}, {10, 5}, {20, 12}};
  std::vector<QPoint> clicks;
  for (const QPoint& off : wanted) {
    std::optional<QPoint> found;
    for (int r = 0; r <= 40 && !found; r += 2) {
      for (int dy = -r; dy <= r && !found; dy += 2) {
        for (int dx = -r; dx <= r && !found; dx += 2) {
          const QPoint q = c + off + QPoint(dx, dy);
          // Away from the points already chosen (a click on a landmark selects it).
          const bool apart = std::all_of(clicks.begin(), clicks.end(),
                                         [&](const QPoint& o) { return std::hypot(o.x() - q.x(), o.y() - q.y()) > 12; });
          if (apart && lm->pick_surface(q)) found = q;
        }
      }
    }
    ASSERT_TRUE(found.has_value()) << "nothing pickable near offset " << off.x() << "," << off.y();
    clicks.push_back(*found);
  }

  // Eight clicks: four pairs, sets alternating 1, 2, 1, 2, ...
  for (size_t i = 0; i < clicks.size(); ++i) {
    const int set = static_cast<int>(i % 2), pair = static_cast<int>(i / 2);
    EXPECT_EQ(s->active_set(), set);
    const auto expected = lm->pick_surface(clicks[i]);
    ASSERT_TRUE(expected.has_value());
    QTest::mouseClick(vtk, Qt::LeftButton, Qt::NoModifier, clicks[i]);
    ASSERT_EQ(s->pair_count(), pair + 1) << i << w.log_text().toStdString();
    const auto p = s->point(pair, set);
    ASSERT_TRUE(p.has_value()) << i;
    EXPECT_LT(dist(*p, *expected), 1e-9) << i;
    // On one of the three slice planes, inside the volume, and drawn where it was clicked.
    double on_plane = 1e300;
    for (int k = 0; k < 3; ++k) on_plane = std::min(on_plane, std::abs((*p)[k] - plane[k]));
    EXPECT_LT(on_plane, 1e-3) << i << ": " << (*p)[0] << " " << (*p)[1] << " " << (*p)[2];
    for (int k = 0; k < 3; ++k) {
      EXPECT_GE((*p)[k], grid.origin[k] - 0.5 * grid.spacing[k] - 1e-6) << i;
      EXPECT_LE((*p)[k], grid.origin[k] + (grid.dims[k] - 0.5) * grid.spacing[k] + 1e-6) << i;
    }
    const auto sp = lm->screen_position_f(*p);
    ASSERT_TRUE(sp.has_value());
    EXPECT_LT(std::hypot(sp->first - (clicks[i].x() + 0.5), sp->second - (clicks[i].y() + 0.5)), 1.0) << i;
    EXPECT_EQ(lm->selected_pair(), pair);
  }
  EXPECT_EQ(s->undo_stack()->count(), 8);
  ASSERT_EQ(s->complete_count(), 4);
  ASSERT_TRUE(s->has_fit()) << s->fit_error().toStdString();
  auto fixed_of = [&] {
    std::vector<Vec3> f, m;
    for (int i = 0; i < s->pair_count(); ++i) {
      f.push_back(*s->point(i, 0));
      m.push_back(*s->point(i, 1));
    }
    return std::make_pair(f, m);
  };
  {
    const auto [f, m] = fixed_of();
    const auto ref = registration::fit_landmarks(f, m, TransformKind::Rigid);
    EXPECT_NEAR(s->rms(), ref.rms, 1e-12);
    for (int i = 0; i < 4; ++i) EXPECT_NEAR(s->residual(i), ref.distance[static_cast<size_t>(i)], 1e-12);
  }
  // The dock's table: four pairs and the RMS row.
  QTableView* table = lm->table();
  ASSERT_EQ(table->model()->rowCount(), 5);
  EXPECT_EQ(table->model()->index(4, 0).data().toString(), "RMS");
  EXPECT_EQ(table->model()->index(4, LandmarkSession::ColResidual).data().toString(), QString::number(s->rms(), 'g', 4));
  QTest::qWait(50);
  save_shot(w.view3d()->grab_image(), "landmarks_view.png");
  save_shot(w.grab().toImage(), "landmarks_window.png");

  // A click on a landmark selects its pair and places nothing.
  const auto on3 = lm->screen_position(*s->point(2, 1));
  ASSERT_TRUE(on3.has_value());
  QTest::mouseClick(vtk, Qt::LeftButton, Qt::NoModifier, *on3);
  EXPECT_EQ(s->pair_count(), 4);
  EXPECT_EQ(lm->selected_pair(), 2);
  EXPECT_EQ(s->undo_stack()->count(), 8);

  // Drag the set-1 point of pair 1 onto another pickable position: it lands where the picker says,
  // as one undo step, and the residuals follow.
  const double rms_before = s->rms();
  const Vec3 p0 = *s->point(0, 0);
  const auto from = lm->screen_position(p0);
  ASSERT_TRUE(from.has_value());
  const auto grabbed = lm->pick_landmark(*from);
  ASSERT_TRUE(grabbed.has_value());
  ASSERT_EQ(grabbed->first, 0);
  ASSERT_EQ(grabbed->second, 0);
  QPoint to = *from + QPoint(35, 25);
  for (int k = 0; k < 20 && !lm->pick_surface(to); ++k) to += QPoint(2, 1);
  const auto target = lm->pick_surface(to);
  ASSERT_TRUE(target.has_value());
  QTest::mousePress(vtk, Qt::LeftButton, Qt::NoModifier, *from);
  for (int k = 1; k <= 5; ++k) QTest::mouseMove(vtk, *from + (to - *from) * k / 5);
  QTest::mouseRelease(vtk, Qt::LeftButton, Qt::NoModifier, to);
  EXPECT_EQ(s->pair_count(), 4);
  EXPECT_EQ(s->undo_stack()->count(), 9);
  EXPECT_LT(dist(*s->point(0, 0), *target), 1e-9);
  EXPECT_GT(dist(*s->point(0, 0), p0), 1.0);
  {
    const auto [f, m] = fixed_of();
    const auto ref = registration::fit_landmarks(f, m, TransformKind::Rigid);
    EXPECT_NEAR(s->rms(), ref.rms, 1e-12);
    EXPECT_NE(s->rms(), rms_before);
  }

  // Keys of the 3D view: Ctrl+Z undoes the drag (not a pipeline edit), Ctrl+Shift+Z redoes it.
  const int doc_undo = w.document()->undo_stack()->count();
  QTest::keyClick(vtk, Qt::Key_Z, Qt::ControlModifier);
  EXPECT_LT(dist(*s->point(0, 0), p0), 1e-12);
  EXPECT_NEAR(s->rms(), rms_before, 1e-12);
  QTest::keyClick(vtk, Qt::Key_Z, Qt::ControlModifier | Qt::ShiftModifier);
  EXPECT_LT(dist(*s->point(0, 0), *target), 1e-9);
  EXPECT_EQ(w.document()->undo_stack()->count(), doc_undo);
  QTest::keyClick(vtk, Qt::Key_2);
  EXPECT_EQ(s->active_set(), 1);
  QTest::keyClick(vtk, Qt::Key_1);
  EXPECT_EQ(s->active_set(), 0);
  const auto pairs_saved = s->pairs();
  const double rms_saved = s->rms();

  // Save: the .landmarkAscii file and the pipeline nodes; running them reproduces the RMS.
  const QString file = QDir(tmp.path()).filePath("landmarks.landmarkAscii");
  EXPECT_EQ(lm->default_path(), file);
  ASSERT_TRUE(lm->save()) << w.log_text().toStdString();
  const LandmarkSet saved = io::read_landmarks(file.toStdString());
  ASSERT_EQ(saved.set_count(), 2);
  ASSERT_EQ(saved.point_count(), 4);
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_LT(dist(saved.sets[0][i], *pairs_saved[i].p[0]), 1e-9);
    EXPECT_LT(dist(saved.sets[1][i], *pairs_saved[i].p[1]), 1e-9);
  }
  const PipelineNode* read_node = w.document()->pipeline().find("read_landmarks");
  ASSERT_NE(read_node, nullptr) << w.document()->to_yaml().toStdString();
  EXPECT_EQ(read_node->module, "io.read_landmarks");
  EXPECT_EQ(std::get<std::string>(read_node->params.at("path")), "landmarks.landmarkAscii");
  const PipelineNode* fit_node = w.document()->pipeline().find("landmarks");
  ASSERT_NE(fit_node, nullptr) << w.document()->to_yaml().toStdString();
  EXPECT_EQ(fit_node->module, "registration.landmarks");
  EXPECT_EQ(fit_node->inputs.at("landmarks").str(), "read_landmarks.landmarks");
  ASSERT_TRUE(run_and_wait(w, 60000, {"landmarks"}));
  auto residuals = std::dynamic_pointer_cast<const Table>(w.runner()->output("landmarks", "table"));
  ASSERT_NE(residuals, nullptr) << w.log_text().toStdString();
  ASSERT_EQ(residuals->rows(), 5);
  EXPECT_EQ(residuals->cell(0, 4), "RMS");
  EXPECT_NEAR(std::stod(residuals->cell(residuals->columns().size() - 1, 4)), rms_saved, 1e-6);

  // Delete the selected pair with the Delete key, then clear everything and reload the file.
  lm->select_pair(3);
  QTest::keyClick(vtk, Qt::Key_Delete);
  EXPECT_EQ(s->pair_count(), 3);
  ASSERT_TRUE(s->clear_all());
  EXPECT_EQ(s->pair_count(), 0);
  EXPECT_EQ(table->model()->rowCount(), 0);
  ASSERT_TRUE(lm->load(file));
  ASSERT_EQ(s->pair_count(), 4);
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_LT(dist(*s->point(static_cast<int>(i), 0), *pairs_saved[i].p[0]), 1e-9);
    EXPECT_LT(dist(*s->point(static_cast<int>(i), 1), *pairs_saved[i].p[1]), 1e-9);
  }
  EXPECT_NEAR(s->rms(), rms_saved, 1e-9);
  EXPECT_EQ(table->model()->rowCount(), 5);

  // Picking on an iso-surface: the placed point lies where the image crosses the iso value.
  w.view3d()->set_volume_mode("phantom.image", VolumeMode::IsoSurface);
  w.view3d()->set_iso_value("phantom.image", 0.5);
  QTest::qWait(50);
  std::optional<QPoint> on_surface;
  for (int r = 0; r <= 120 && !on_surface; r += 3) {
    for (int dy = -r; dy <= r && !on_surface; dy += 3) {
      for (int dx = -r; dx <= r && !on_surface; dx += 3) {
        const QPoint q = c + QPoint(dx, dy);
        if (!lm->pick_landmark(q) && lm->pick_surface(q)) on_surface = q;
      }
    }
  }
  ASSERT_TRUE(on_surface.has_value());
  EXPECT_EQ(s->active_set(), 0);
  QTest::mouseClick(vtk, Qt::LeftButton, Qt::NoModifier, *on_surface);
  ASSERT_EQ(s->pair_count(), 5);
  const auto iso_point = s->point(4, 0);
  ASSERT_TRUE(iso_point.has_value());
  EXPECT_NEAR(trilinear(*image, *iso_point), 0.5, 0.05)
      << (*iso_point)[0] << " " << (*iso_point)[1] << " " << (*iso_point)[2];
  const auto iso_screen = lm->screen_position_f(*iso_point);
  ASSERT_TRUE(iso_screen.has_value());
  EXPECT_LT(std::hypot(iso_screen->first - (on_surface->x() + 0.5), iso_screen->second - (on_surface->y() + 0.5)), 1.0);

  // Leaving keeps the landmarks; the graph edit mode's menu entry would leave this mode.
  QDockWidget* dock = lm->dock();
  lm->stop();
  EXPECT_FALSE(lm->active());
  EXPECT_EQ(lm->dock(), nullptr);
  EXPECT_EQ(s->pair_count(), 5);
  QTest::qWait(20);
  EXPECT_FALSE(w.findChildren<QDockWidget*>().contains(dock));
  // Opening another pipeline clears them.
  ASSERT_TRUE(w.open_file(pipeline));
  EXPECT_EQ(s->pair_count(), 0);
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
  QApplication::setApplicationName("gui_landmark_test");
  return RUN_ALL_TESTS();
}
