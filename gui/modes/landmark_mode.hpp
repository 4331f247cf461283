#pragma once
// Landmark mode of the 3D view (issue 9, thesis §6.2): click on whatever the 3D view shows (a slice,
// an iso-surface, a voxel surface, a graph) to place a landmark there (vtkCellPicker), drag a
// landmark to move it along the surfaces, numbered pairs drawn in two colours on an overlay layer
// (set 1 = fixed: orange, set 2 = moving: cyan, a thin line joins the points of a pair), and a
// "Landmarks" dock with the residual table of the LandmarkSession (the model; no VTK there), the
// registration model, load / save (.landmarkAscii) and undo / redo. Event filter, overlay layer, dock
// and the undo keys are InteractionMode's.
//
// Mouse: a click (press and release within 3 px) on a surface places a point in the active set;
// press on a landmark and drag to move it (the camera does not turn); a click on a landmark selects
// its pair; a drag elsewhere turns the camera as usual. Keys (3D view focused): 1 / 2 choose the
// active set, Delete / Backspace delete the selected pair, Ctrl+Z undo, Ctrl+Shift+Z / Ctrl+Y redo,
// Esc clears the selection.
#include <QPoint>
#include <QString>

#include <memory>
#include <optional>

#include "interaction_mode.hpp"
#include "landmark_session.hpp"

class QComboBox;
class QDockWidget;
class QLabel;
class QRadioButton;
class QTableView;
class QWidget;

namespace skel::gui {

class LandmarkMode : public InteractionMode {
  Q_OBJECT
public:
  explicit LandmarkMode(MainWindow* window);
  ~LandmarkMode() override;

  // Shows the overlay and the dock and takes the 3D view's mouse. The landmarks live as long as the
  // window (leaving the mode keeps them; opening another pipeline clears them).
  void start();
  void stop() override;
  [[nodiscard]] bool active() const override { return active_; }
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

  [[nodiscard]] int selected_pair() const { return selected_; }
  void select_pair(int pair);
  [[nodiscard]] QDockWidget* dock() const { return dock_; }
  [[nodiscard]] QTableView* table() const { return table_; }
  [[nodiscard]] QLabel* status_label() const { return status_; }

protected:
  [[nodiscard]] QUndoStack* undo_stack() const override;
  bool mouse_press(QMouseEvent* event) override;
  bool mouse_move(QMouseEvent* event) override;
  bool mouse_release(QMouseEvent* event, bool click) override;

private:
  void build_dock();
  void refresh();  // overlay + status

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
  // A press on empty space may become a click (place) or a camera drag; a press on a landmark starts
  // a drag of that landmark.
  int drag_pair_ = -1, drag_set_ = -1;
  std::optional<Vec3> drag_to_;
};

}  // namespace skel::gui
