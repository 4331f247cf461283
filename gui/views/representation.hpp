#pragma once
// One data object shown in the 3D view: the VTK props that draw it for its display settings and the
// side-panel page that changes those settings. One subclass per data type (volume_representation,
// graph_representation); View3D owns the renderer, the camera, the object list and the shared
// scalar bar, and asks make_representation() for the class that shows a given data object. A view
// of a new type is one more subclass and one more line in make_representation().
#include <QString>

#include <vtkSmartPointer.h>

#include <array>
#include <functional>
#include <memory>
#include <vector>

#include "skel/data.hpp"

class QWidget;
class vtkProp;
class vtkScalarBarActor;

namespace skel::gui {

using Color = std::array<double, 3>;

class Representation {
public:
  Representation(QString name, DataPtr data, const Color& color);
  virtual ~Representation();
  Representation(const Representation&) = delete;
  Representation& operator=(const Representation&) = delete;

  [[nodiscard]] const QString& name() const { return name_; }
  [[nodiscard]] const DataPtr& data() const { return data_; }
  [[nodiscard]] const Color& color() const { return color_; }
  [[nodiscard]] bool visible() const { return visible_; }
  void set_visible(bool visible) { visible_ = visible; }

  // New data for a shown object (e.g. after a re-run) keeps how the object was displayed: its colour
  // and visibility, and the type's own settings when `old` shows the same kind of data.
  void keep_display_of(const Representation& old);

  // The props that draw the data with the current settings (called only while visible). A
  // representation that colours by a value range sets `bar`'s lookup table and title here.
  [[nodiscard]] virtual std::vector<vtkSmartPointer<vtkProp>> build_props(vtkScalarBarActor* bar) = 0;
  // True while the scalar bar should show this object's colours (when it is visible).
  [[nodiscard]] virtual bool uses_scalar_bar() const { return false; }

  // The side-panel page of this object, made on first use; the caller takes ownership (a Qt
  // parent) and deletes it before the representation.
  [[nodiscard]] virtual QWidget* create_controls() = 0;
  // Sets the page's widgets from the current settings (no-op before create_controls()).
  virtual void update_controls() = 0;

  // What the page calls after changing a setting: the view rebuilds the props and renders.
  void on_changed(std::function<void()> f) { changed_ = std::move(f); }

protected:
  // The type's part of keep_display_of(); `old` may be of another type.
  virtual void keep_settings(const Representation& old) = 0;
  void changed() {
    if (changed_) changed_();
  }

  // Set while update_controls() writes the widgets, so their change signals are not user edits.
  bool syncing_ = false;

private:
  QString name_;
  DataPtr data_;
  Color color_;
  bool visible_ = true;
  std::function<void()> changed_;
};

// The representation for `data`: a graph, else a volume. Null with *error set for other types.
std::unique_ptr<Representation> make_representation(const QString& name, const DataPtr& data, const Color& color,
                                                    QString* error);

}  // namespace skel::gui
