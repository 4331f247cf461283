#pragma once
// Main window of skelflow-gui: node editor in the centre, module palette and properties in docks,
// 3D view beside the editor, log and table docks below; File / Edit / View / Run menus.
#include <QMainWindow>
#include <QPointer>

#include "pipeline_document.hpp"
#include "run_controller.hpp"

class QAction;
class QLabel;
class QMenu;
class QPlainTextEdit;
class QProgressBar;
class QSplitter;
class QTableWidget;

namespace skel::gui {

class GraphEditMode;
class LandmarkMode;
class NodeScene;
class NodeView;
class Palette;
class PropertiesPanel;
class View3D;

class MainWindow final : public QMainWindow {
  Q_OBJECT
public:
  explicit MainWindow(QWidget* parent = nullptr);
  ~MainWindow() override;

  // Files. open_file/save_file report errors in the log and return false (no dialogs).
  bool open_file(const QString& path);
  bool save_file(const QString& path);
  // Asks to save unsaved changes; false if the user cancels.
  bool maybe_save();
  [[nodiscard]] QStringList recent_files() const;

  // Runs the whole pipeline / what the selected nodes need.
  void run_all();
  void run_selected();
  void cancel_run();
  // Shows a node's output port in the 3D view (volumes, graphs) or the table dock (tables); runs
  // the pipeline up to that node first if the output is not computed.
  bool show_output(const QString& node, const QString& port);
  // After a successful run, unless the user has chosen what to show (clicked an output port) since
  // the pipeline was opened and while the view is empty, the run's final geometry is shown by itself
  // (final_outputs.hpp: the sink-most mesh and graph, else the last volume). Returns what it shows.
  QStringList show_final_geometry();
  // Edit mode on a computed graph output (docs/editing.md); false (logged) if it is not one.
  bool edit_graph(const QString& node, const QString& port);

  [[nodiscard]] PipelineDocument* document() const { return doc_; }
  [[nodiscard]] RunController* runner() const { return run_; }
  [[nodiscard]] NodeScene* scene() const { return scene_; }
  [[nodiscard]] NodeView* node_view() const { return view_; }
  [[nodiscard]] View3D* view3d() const { return view3d_; }
  [[nodiscard]] PropertiesPanel* properties() const { return props_; }
  [[nodiscard]] Palette* palette() const { return palette_; }
  [[nodiscard]] QProgressBar* progress_bar() const { return progress_; }
  [[nodiscard]] QTableWidget* table_view() const { return table_; }
  [[nodiscard]] GraphEditMode* graph_edit() const { return edit_; }
  // Landmark mode of the 3D view (docs/landmarks.md); leaves the graph edit mode.
  void edit_landmarks();
  [[nodiscard]] LandmarkMode* landmark_mode() const { return landmarks_; }

  void log(const QString& text, bool error = false);
  [[nodiscard]] QString log_text() const;

protected:
  void closeEvent(QCloseEvent* e) override;

private:
  void build_actions();
  void update_title();
  void add_recent(const QString& path);
  void rebuild_recent_menu();
  void copy_selection();
  void paste_clipboard();
  void show_table(const QString& name, const DataPtr& data);
  void update_run_actions();

  PipelineDocument* doc_;
  RunController* run_;
  NodeScene* scene_;
  NodeView* view_;
  Palette* palette_;
  PropertiesPanel* props_;
  View3D* view3d_;
  QSplitter* split_;
  QPlainTextEdit* log_;
  QTableWidget* table_;
  GraphEditMode* edit_ = nullptr;
  LandmarkMode* landmarks_ = nullptr;
  QProgressBar* progress_;
  QLabel* status_label_;
  QMenu* recent_menu_ = nullptr;
  QAction* run_all_ = nullptr;
  QAction* run_selected_ = nullptr;
  QAction* cancel_ = nullptr;
  QString pending_node_, pending_port_;  // output to show when the current run ends
  bool view_chosen_ = false;             // the user showed an output since the pipeline was opened
  int paste_count_ = 0;
};

}  // namespace skel::gui
