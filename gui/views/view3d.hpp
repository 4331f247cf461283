#pragma once
// 3D view (VTK in a QVTKOpenGLNativeWidget) showing several data objects at once, each with a
// visibility toggle. View3D keeps the renderer, the camera, the object list and the scalar bar; how
// each object is drawn, and its display controls, belong to its Representation (one class per data
// type: volume_representation, graph_representation).
#include <QImage>
#include <QMap>
#include <QWidget>

#include <memory>

#include "graph_representation.hpp"
#include "mesh_representation.hpp"
#include "skel/data.hpp"
#include "volume_representation.hpp"

class QListWidget;
class QStackedWidget;
class QVTKOpenGLNativeWidget;
class vtkRenderer;

namespace skel::gui {

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

  // Display settings of volume and graph objects (ignored for objects of another type).
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
  // The VTK widget (interaction modes filter its mouse and key events).
  [[nodiscard]] QWidget* vtk_widget() const;

signals:
  void message(const QString& text);

private:
  struct Object {
    std::unique_ptr<Representation> rep;
    std::vector<vtkSmartPointer<vtkProp>> props;  // in the renderer now
    QWidget* controls = nullptr;                  // its page in controls_, made when first selected
  };
  void apply(Object& o);  // (re)builds the props of an object for its settings and visibility
  void update_scalar_bar();
  void select_object(const QString& name);
  void update_controls();
  template <class R>
  R* find(const QString& name) const;

  QVTKOpenGLNativeWidget* vtk_;
  struct Vtk;
  std::unique_ptr<Vtk> vtk_state_;
  QMap<QString, std::shared_ptr<Object>> objects_;
  QString current_;
  bool updating_controls_ = false;

  QListWidget* list_;
  QStackedWidget* controls_;
};

}  // namespace skel::gui
