#pragma once
// Common part of the 3D view's interaction modes (graph editing, landmarks): while active, a mode
// filters the view's key and mouse events, draws on an overlay renderer (layer 1, sharing the main
// camera, so its points stay visible in front of the data) and shows its docks in the main window.
// Ctrl+Z undoes, Ctrl+Shift+Z / Ctrl+Y redo on the mode's undo stack; other keys (without Ctrl) are
// bound by the mode with bind_key(). Bound keys are taken from the window's shortcuts while the 3D
// view has the focus. A left press and release within kClickSlack pixels is a click.
#include <QObject>
#include <QPoint>
#include <QString>

#include <vtkCellArray.h>
#include <vtkPoints.h>
#include <vtkSmartPointer.h>

#include <array>
#include <functional>
#include <map>
#include <optional>
#include <utility>
#include <vector>

#include "graph_pick.hpp"

class QDockWidget;
class QMouseEvent;
class QUndoStack;
class QWidget;
class vtkActor;
class vtkRenderer;

namespace skel::gui {

class MainWindow;
class View3D;

class InteractionMode : public QObject {
  Q_OBJECT
public:
  ~InteractionMode() override;

  [[nodiscard]] virtual bool active() const = 0;
  // Leaves the mode (nothing happens when it is not active).
  virtual void stop() = 0;

  // Runs the action bound to `key` (as the event filter does); false if the key is not bound or the
  // mode is not active.
  bool handle_key(int key, Qt::KeyboardModifiers modifiers);

  // The 3D view's camera as a screen projection in widget coordinates.
  [[nodiscard]] ScreenProjection projection() const;
  // Widget position of a world point: continuous (pixel centres at +0.5) and as the pixel it falls
  // in; nullopt if not visible.
  [[nodiscard]] std::optional<std::pair<double, double>> screen_position_f(const Vec3& p) const;
  [[nodiscard]] std::optional<QPoint> screen_position(const Vec3& p) const;
  [[nodiscard]] QWidget* vtk_widget() const { return vtk_widget_; }

signals:
  void started();
  void stopped();

protected:
  static constexpr double kPickRadius = 8.0;  // pixels
  static constexpr int kClickSlack = 3;       // pixels a click may move and still be a click

  explicit InteractionMode(MainWindow* window);

  // What Ctrl+Z / Ctrl+Shift+Z / Ctrl+Y act on while active.
  [[nodiscard]] virtual QUndoStack* undo_stack() const = 0;
  // Binds `key` without Ctrl (with or without Shift) to `action`.
  void bind_key(int key, std::function<void()> action);
  // Left-button events of the 3D view while active; true keeps them from the camera. The press
  // position is press_pos(); `click`: the release is within kClickSlack pixels of it.
  virtual bool mouse_press(QMouseEvent* /*event*/) { return false; }
  virtual bool mouse_move(QMouseEvent* /*event*/) { return false; }  // any button, pressed or not
  virtual bool mouse_release(QMouseEvent* /*event*/, bool /*click*/) { return false; }
  [[nodiscard]] QPoint press_pos() const { return press_pos_; }
  [[nodiscard]] bool pressed() const { return pressed_; }
  [[nodiscard]] bool is_click(QPoint pos) const { return (pos - press_pos_).manhattanLength() <= kClickSlack; }

  // Entering: the overlay renderer (returned; add the mode's actors to it), then take the view's
  // events and focus. Leaving: release() undoes both and removes the docks added with add_dock().
  vtkRenderer* open_overlay();
  void take_input();
  void release();
  [[nodiscard]] vtkRenderer* overlay() const;
  // Adds a dock on the window's right; release() removes it.
  QDockWidget* add_dock(const QString& title, const QString& object_name, QWidget* content);

  // An overlay actor for points (spheres, unlit) and lines, with empty poly data.
  static vtkSmartPointer<vtkActor> make_overlay_actor(const std::array<double, 3>& color, double point_size,
                                                      double line_width);
  // Points as vertices plus polylines, in one poly data, for an overlay actor.
  struct OverlayShape {
    vtkSmartPointer<vtkPoints> points = vtkSmartPointer<vtkPoints>::New();
    vtkSmartPointer<vtkCellArray> verts = vtkSmartPointer<vtkCellArray>::New();
    vtkSmartPointer<vtkCellArray> lines = vtkSmartPointer<vtkCellArray>::New();
    void vertex(const Vec3& p);
    void line(const std::vector<Vec3>& pts);
    void set(vtkActor* actor) const;
  };

  // Default folder of the files a mode writes: SKELFLOW_EDIT_DIR, else the pipeline file's folder,
  // else the current folder.
  [[nodiscard]] QString default_dir() const;
  void log(const QString& text, bool error = false);

  // Keys go to handle_key(), left-button events to mouse_press/move/release.
  bool eventFilter(QObject* watched, QEvent* event) override;

  MainWindow* window_;
  View3D* view_;
  QWidget* vtk_widget_;

private:
  [[nodiscard]] bool is_bound(int key, Qt::KeyboardModifiers modifiers) const;

  std::map<int, std::function<void()>> keys_;
  vtkSmartPointer<vtkRenderer> overlay_;
  std::vector<QDockWidget*> docks_;
  QPoint press_pos_;
  bool pressed_ = false;
};

}  // namespace skel::gui
