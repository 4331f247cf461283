#pragma once
// Edit mode of the 3D view on a graph output (thesis §6.1, fig. 6.4; issue 10): the edited graph is
// drawn as lines over the pipeline's original image (MIP), picks and box selections go through
// graph_pick (screen-space projection of every point: no locator to rebuild after an edit), the
// selection and the dangling-end proposal are drawn on an overlay layer, and keys run the
// GraphEditSession's operations. Two docks: "Graph editing" (buttons, route, status) and
// "Edit history" (QUndoView of the session's undo stack).
//
// Keys (when the 3D view has the focus): Delete/Backspace delete, C connect, S split, M merge,
// N next dangling end, Enter/Return/A accept the proposed connection, Space/K skip the end,
// Ctrl+Z undo, Ctrl+Shift+Z / Ctrl+Y redo, Esc clear the selection. Mouse: click selects the nearest
// node or edge point (within 8 px), Ctrl+click adds/removes, Shift+drag selects a box.
#include <QObject>
#include <QPoint>
#include <QPointer>
#include <QString>

#include <memory>
#include <optional>

#include "edit_session.hpp"
#include "graph_pick.hpp"

class QComboBox;
class QDockWidget;
class QLabel;
class QRubberBand;
class QUndoView;
class QWidget;
class vtkActor;
class vtkRenderer;

namespace skel::gui {

class MainWindow;
class View3D;

class GraphEditMode : public QObject {
  Q_OBJECT
public:
  enum class ResumePolicy { Ask, Replay, StartOver };

  explicit GraphEditMode(MainWindow* window);
  ~GraphEditMode() override;

  // Enters edit mode on output node.port (it must be computed). Journal: `journal_path` or, when
  // empty, `<journal dir>/<node>.<port>.edits.yaml`. Returns false (and logs why) on failure.
  bool start(const QString& node, const QString& port, const QString& journal_path = {});
  void stop();
  [[nodiscard]] bool active() const { return static_cast<bool>(session_); }
  [[nodiscard]] GraphEditSession* session() const { return session_.get(); }

  // Where journals and saved graphs go by default: the environment variable SKELFLOW_EDIT_DIR, else
  // the pipeline file's folder, else the current folder.
  void set_journal_dir(const QString& dir) { journal_dir_ = dir; }
  [[nodiscard]] QString journal_dir() const;
  // What to do when the journal exists: ask (dialog), replay or start over. The environment variable
  // SKELFLOW_EDIT_RESUME=replay|restart overrides Ask (for scripted use and tests).
  void set_resume_policy(ResumePolicy p) { resume_policy_ = p; }

  // Save: writes `<base>.am` and `<base>.vtp` (default base: `<journal dir>/<node>.<port>.edited`)
  // and adds graph.apply_edits after the graph's producer in the pipeline document.
  bool save(const QString& base = {});

  // Picking in the 3D view's widget coordinates.
  [[nodiscard]] ScreenProjection projection() const;
  [[nodiscard]] GraphPick pick(QPoint widget_pos) const;
  // Widget position of a world point (for tests and the tour); nullopt if not visible.
  [[nodiscard]] std::optional<QPoint> screen_position(const Vec3& p) const;
  // Camera looks at p from its current direction, at a distance showing `extent` around it.
  void focus(const Vec3& p, double extent);
  [[nodiscard]] QWidget* vtk_widget() const { return vtk_widget_; }
  [[nodiscard]] QString object_name() const { return object_; }      // the edited graph in the 3D view
  [[nodiscard]] QString background_name() const { return background_; }  // image under it, or empty
  [[nodiscard]] QDockWidget* panel_dock() const { return panel_dock_; }
  [[nodiscard]] QDockWidget* history_dock() const { return history_dock_; }
  [[nodiscard]] QUndoView* history_view() const { return history_; }

  // Runs the action bound to `key` (as the event filter does); false if the key is not bound.
  bool handle_key(int key, Qt::KeyboardModifiers modifiers);

signals:
  void started();
  void stopped();

protected:
  bool eventFilter(QObject* watched, QEvent* event) override;

private:
  void build_docks();
  void refresh_graph();
  void refresh_overlay();
  void update_status();
  void next_and_focus(bool skip);
  void log(const QString& text, bool error = false);

  MainWindow* window_;
  View3D* view_;
  QWidget* vtk_widget_;
  std::unique_ptr<GraphEditSession> session_;
  QString node_, port_, object_, background_, mask_port_, distance_port_;
  QString journal_dir_;
  ResumePolicy resume_policy_ = ResumePolicy::Ask;
  bool original_was_visible_ = false;

  struct Overlay;
  std::unique_ptr<Overlay> overlay_;
  QDockWidget* panel_dock_ = nullptr;
  QDockWidget* history_dock_ = nullptr;
  QUndoView* history_ = nullptr;
  QLabel* status_ = nullptr;
  QComboBox* route_ = nullptr;
  // Mouse state.
  QPoint press_pos_;
  bool pressed_ = false, box_ = false;
  QRubberBand* rubber_ = nullptr;
};

}  // namespace skel::gui
