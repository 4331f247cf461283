#pragma once
// 3D view (VTK in a QVTKOpenGLNativeWidget) showing several data objects at once, each with a
// visibility toggle. Volumes: three orthogonal slices with window/level, maximum-intensity
// projection, iso-surface, volume rendering; binary masks and skeletons: voxel surfaces. Graphs:
// lines or tubes (radius attribute) coloured by any point/edge attribute with a scalar bar.
#include <QImage>
#include <QMap>
#include <QWidget>

#include <memory>

#include "skel/data.hpp"

class QCheckBox;
class QComboBox;
class QDoubleSpinBox;
class QListWidget;
class QListWidgetItem;
class QSlider;
class QStackedWidget;
class QVTKOpenGLNativeWidget;
class vtkRenderer;
class vtkGenericOpenGLRenderWindow;

namespace skel::gui {

enum class VolumeMode { Slices, Mip, IsoSurface, VolumeRendering, VoxelSurface };
enum class GraphMode { Lines, Tubes };

class View3D final : public QWidget {
  Q_OBJECT
public:
  explicit View3D(QWidget* parent = nullptr);
  ~View3D() override;

  // Shows `data` as object `name` (replacing an object of that name). Volumes and graphs are
  // supported; returns false with *error set for other types.
  bool show_data(const QString& name, const DataPtr& data, QString* error = nullptr);
  void remove_object(const QString& name);
  void clear();
  [[nodiscard]] QStringList object_names() const;
  [[nodiscard]] bool has_object(const QString& name) const;
  [[nodiscard]] DataPtr object_data(const QString& name) const;
  void set_object_visible(const QString& name, bool visible);
  [[nodiscard]] bool object_visible(const QString& name) const;

  void set_volume_mode(const QString& name, VolumeMode mode);
  [[nodiscard]] VolumeMode volume_mode(const QString& name) const;
  void set_window_level(const QString& name, double window, double level);
  void set_iso_value(const QString& name, double value);
  void set_graph_mode(const QString& name, GraphMode mode);
  void set_graph_color_by(const QString& name, const QString& attribute);  // empty: plain colour

  void reset_camera();
  void render();
  // The rendered image (what the user sees in the 3D panel).
  [[nodiscard]] QImage grab_image();
  bool save_screenshot(const QString& path);
  [[nodiscard]] vtkRenderer* renderer() const;

signals:
  void message(const QString& text);

private:
  struct Object;
  void apply(Object& o);            // (re)builds the props of an object for its mode and visibility
  void select_object(const QString& name);
  void update_controls();
  Object* current();

  QVTKOpenGLNativeWidget* vtk_;
  struct Vtk;
  std::unique_ptr<Vtk> vtk_state_;
  QMap<QString, std::shared_ptr<Object>> objects_;
  QString current_;
  bool updating_controls_ = false;

  QListWidget* list_;
  QStackedWidget* controls_;
  QComboBox* volume_mode_;
  QDoubleSpinBox* window_;
  QDoubleSpinBox* level_;
  QSlider* slice_[3];
  QDoubleSpinBox* iso_;
  QComboBox* graph_mode_;
  QComboBox* color_by_;
  QDoubleSpinBox* tube_scale_;
};

}  // namespace skel::gui
