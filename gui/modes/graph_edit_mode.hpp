#pragma once
// Edit mode of the 3D view on a graph output (thesis §6.1, fig. 6.4; issue 10): the edited graph is
// drawn as lines over the pipeline's original image (MIP), picks and box selections go through
// graph_pick (screen-space projection of every point: no locator to rebuild after an edit), the
// selection and the dangling-end proposal are drawn on an overlay layer, and keys run the
// GraphEditSession's operations. Two docks: "Graph editing" (buttons, route, status) and
// "Edit history" (QUndoView of the session's undo stack). Event filter, overlay layer, docks and the
// undo keys are InteractionMode's.
//
// Keys (when the 3D view has the focus): Delete/Backspace delete, C connect, S split, M merge,
// N next dangling end, Enter/Return/A accept the proposed connection, Space/K skip the end,
// Ctrl+Z undo, Ctrl+Shift+Z / Ctrl+Y redo, Esc clear the selection. Mouse: click selects the nearest
// node or edge point (within 8 px), Ctrl+click adds/removes, Shift+drag selects a box.
#include <QPoint>
#include <QString>

#include <memory>
#include <optional>

#include "edit_session.hpp"
#include "graph_pick.hpp"
#include "interaction_mode.hpp"

class QComboBox;
class QDockWidget;
class QLabel;
class QRubberBand;
class QUndoView;
class QWidget;

namespace skel::gui {

class GraphEditMode : public InteractionMode {
  Q_OBJECT
public:
  enum class ResumePolicy { Ask, Replay, StartOver };

  explicit GraphEditMode(MainWindow* window);
  ~GraphEditMode() override;

  // Enters edit mode on output node.port (it must be computed). Journal: `journal_path` or, when
  // empty, `<journal dir>/<node>.<port>.edits.yaml`. Returns false (and logs why) on failure.
  bool start(const QString& node, const QString& port, const QString& journal_path = {});
  void stop() override;
  [[nodiscard]] bool active() const override { return static_cast<bool>(session_); }
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

  // The node or edge point nearest to `widget_pos` (3D view widget coordinates) within 8 px.
  [[nodiscard]] GraphPick pick(QPoint widget_pos) const;
  // Camera looks at p from its current direction, at a distance showing `extent` around it.
  void focus(const Vec3& p, double extent);
  [[nodiscard]] QString object_name() const { return object_; }      // the edited graph in the 3D view
  [[nodiscard]] QString background_name() const { return background_; }  // image under it, or empty
  [[nodiscard]] QDockWidget* panel_dock() const { return panel_dock_; }
  [[nodiscard]] QDockWidget* history_dock() const { return history_dock_; }
  [[nodiscard]] QUndoView* history_view() const { return history_; }

protected:
  [[nodiscard]] QUndoStack* undo_stack() const override;
  bool mouse_press(QMouseEvent* event) override;
  bool mouse_move(QMouseEvent* event) override;
  bool mouse_release(QMouseEvent* event, bool click) override;

private:
  void build_docks();
  void refresh_graph();
  void refresh_overlay();
  void update_status();
  void next_and_focus(bool skip);

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
  // Shift+drag draws a selection box.
  bool box_ = false;
  QRubberBand* rubber_ = nullptr;
};

}  // namespace skel::gui
