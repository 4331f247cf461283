#pragma once
// Landmark mode of the 3D view (issue 9, thesis §6.2): click on whatever the 3D view shows (a slice,
// an iso-surface, a voxel surface, a graph) to place a landmark there (vtkCellPicker), drag a
// landmark to move it along the surfaces, numbered pairs drawn in two colours on an overlay layer
// (set 1 = fixed: orange, set 2 = moving: cyan, a thin line joins the points of a pair), and a
// "Landmarks" dock with the residual table of the LandmarkSession (the model; no VTK there), the
// registration model, load / save (.landmarkAscii) and undo / redo.
//
// Mouse: a click (press and release within 3 px) on a surface places a point in the active set;
// press on a landmark and drag to move it (the camera does not turn); a click on a landmark selects
// its pair; a drag elsewhere turns the camera as usual. Keys (3D view focused): 1 / 2 choose the
// active set, Delete / Backspace delete the selected pair, Ctrl+Z undo, Ctrl+Shift+Z / Ctrl+Y redo,
// Esc clears the selection.
#include <QObject>
#include <QPoint>
#include <QString>

#include <memory>
#include <optional>

#include "landmark_session.hpp"

class QComboBox;
class QDockWidget;
class QLabel;
class QRadioButton;
class QTableView;
class QWidget;

namespace skel::gui {

class MainWindow;
class View3D;

class LandmarkMode : public QObject {
  Q_OBJECT
public:
  explicit LandmarkMode(MainWindow* window);
  ~LandmarkMode() override;

  // Shows the overlay and the dock and takes the 3D view's mouse. The landmarks live as long as the
  // window (leaving the mode keeps them; opening another pipeline clears them).
  void start();
  void stop();
  [[nodiscard]] bool active() const { return active_; }
  [[nodiscard]] LandmarkSession* session() const { return session_; }

  // Default file: SKELFLOW_EDIT_DIR, else the pipeline's folder, else the current folder, +
  // "landmarks.landmarkAscii".
  [[nodiscard]] QString default_path() const;
  // Writes the landmarks (.landmarkAscii unless the extension says otherwise) and adds
  // io.read_landmarks (+ registration.landmarks for two sets) to the pipeline. Logs and returns
  // false on failure.
  bool save(const QString& path = {});
  bool load(const QString& path);

  // Picking in the 3D view's widget coordinates: the surface point under the cursor (nullopt if
  // nothing is hit), and the landmark nearest to the cursor within 8 px (pair, set) or nullopt.
  [[nodiscard]] std::optional<Vec3> pick_surface(QPoint widget_pos) const;
  [[nodiscard]] std::optional<std::pair<int, int>> pick_landmark(QPoint widget_pos) const;
  [[nodiscard]] std::optional<QPoint> screen_position(const Vec3& p) const;
  // Continuous screen position (pixel centres at +0.5) for precise checks.
  [[nodiscard]] std::optional<std::pair<double, double>> screen_position_f(const Vec3& p) const;

  [[nodiscard]] int selected_pair() const { return selected_; }
  void select_pair(int pair);
  [[nodiscard]] QWidget* vtk_widget() const { return vtk_widget_; }
  [[nodiscard]] QDockWidget* dock() const { return dock_; }
  [[nodiscard]] QTableView* table() const { return table_; }
  [[nodiscard]] QLabel* status_label() const { return status_; }

  bool handle_key(int key, Qt::KeyboardModifiers modifiers);

signals:
  void started();
  void stopped();

protected:
  bool eventFilter(QObject* watched, QEvent* event) override;

private:
  void build_dock();
  void refresh();  // overlay + status
  void log(const QString& text, bool error = false);

  MainWindow* window_;
  View3D* view_;
  QWidget* vtk_widget_;
  LandmarkSession* session_;
  bool active_ = false;
  int selected_ = -1;

  struct Overlay;
  std::unique_ptr<Overlay> overlay_;
  QDockWidget* dock_ = nullptr;
  QTableView* table_ = nullptr;
  QLabel* status_ = nullptr;
  QRadioButton* set_button_[2] = {nullptr, nullptr};
  QComboBox* model_ = nullptr;
  // Mouse state: a press on empty space may become a click (place) or a camera drag; a press on a
  // landmark starts a drag of that landmark.
  QPoint press_pos_;
  bool pressed_ = false;
  int drag_pair_ = -1, drag_set_ = -1;
  std::optional<Vec3> drag_to_;
};

}  // namespace skel::gui
