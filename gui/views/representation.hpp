#pragma once
// One data object shown in the 3D view: its render::Display (the data, its display settings and the
// VTK props that draw it; render/skel_render/display.hpp, shared with `skelflow render`) plus the
// side-panel page that changes those settings. One subclass per data type (volume_representation,
// graph_representation, mesh_representation) adds the page; View3D owns the renderer, the camera,
// the object list and the shared scalar bar, and asks make_representation() for the class that shows
// a given data object. A view of a new type is one more Display, one more subclass here and one more
// line in make_representation().
#include <QString>

#include <vtkSmartPointer.h>

#include <functional>
#include <memory>
#include <vector>

#include "skel/data.hpp"
#include "skel_render/display.hpp"

class QWidget;
class vtkProp;
class vtkScalarBarActor;

namespace skel::gui {

using Color = render::Color;

class Representation {
public:
  Representation(QString name, std::unique_ptr<render::Display> display);
  virtual ~Representation();
  Representation(const Representation&) = delete;
  Representation& operator=(const Representation&) = delete;

  [[nodiscard]] const QString& name() const { return name_; }
  [[nodiscard]] const DataPtr& data() const { return display_->data(); }
  [[nodiscard]] const Color& color() const { return display_->color(); }
  [[nodiscard]] bool visible() const { return visible_; }
  void set_visible(bool visible) { visible_ = visible; }
  [[nodiscard]] render::Display& display() { return *display_; }

  // New data for a shown object (e.g. after a re-run) keeps how the object was displayed: its colour
  // and visibility, and the type's own settings when `old` shows the same kind of data.
  void keep_display_of(const Representation& old);

  // The props that draw the data with the current settings (called only while visible). A
  // representation that colours by a value range sets `bar`'s lookup table and title here.
  [[nodiscard]] std::vector<vtkSmartPointer<vtkProp>> build_props(vtkScalarBarActor* bar) {
    return display_->build_props(bar);
  }
  // True while the scalar bar should show this object's colours (when it is visible).
  [[nodiscard]] bool uses_scalar_bar() const { return display_->uses_scalar_bar(); }

  // The side-panel page of this object, made on first use; the caller takes ownership (a Qt
  // parent) and deletes it before the representation.
  [[nodiscard]] virtual QWidget* create_controls() = 0;
  // Sets the page's widgets from the current settings (no-op before create_controls()).
  virtual void update_controls() = 0;

  // What the page calls after changing a setting: the view rebuilds the props and renders.
  void on_changed(std::function<void()> f) { changed_ = std::move(f); }

protected:
  void changed() {
    if (changed_) changed_();
  }

  // Set while update_controls() writes the widgets, so their change signals are not user edits.
  bool syncing_ = false;

private:
  QString name_;
  std::unique_ptr<render::Display> display_;
  bool visible_ = true;
  std::function<void()> changed_;
};

// The representation for `data`: a graph, a mesh, else a volume. Null with *error set for other types.
std::unique_ptr<Representation> make_representation(const QString& name, const DataPtr& data, const Color& color,
                                                    QString* error);

}  // namespace skel::gui
