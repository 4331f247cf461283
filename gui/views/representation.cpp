#include "representation.hpp"

#include <vtkProp.h>

#include "graph_representation.hpp"
#include "mesh_representation.hpp"
#include "skel/error.hpp"
#include "volume_representation.hpp"

namespace skel::gui {

Representation::Representation(QString name, std::unique_ptr<render::Display> display)
    : name_(std::move(name)), display_(std::move(display)) {}

Representation::~Representation() = default;

void Representation::keep_display_of(const Representation& old) {
  display_->set_color(old.color());
  visible_ = old.visible_;
  display_->keep_settings(*old.display_);
}

std::unique_ptr<Representation> make_representation(const QString& name, const DataPtr& data, const Color& color,
                                                    QString* error) {
  std::unique_ptr<render::Display> d;
  try {
    d = render::make_display(data, color);
  } catch (const std::exception& e) {
    if (error) *error = name + ": " + QString::fromUtf8(e.what());
    return nullptr;
  }
  if (auto* g = dynamic_cast<render::GraphDisplay*>(d.get())) {
    d.release();
    return std::make_unique<GraphRepresentation>(name, std::unique_ptr<render::GraphDisplay>(g));
  }
  if (auto* m = dynamic_cast<render::MeshDisplay*>(d.get())) {
    d.release();
    return std::make_unique<MeshRepresentation>(name, std::unique_ptr<render::MeshDisplay>(m));
  }
  auto* v = static_cast<render::VolumeDisplay*>(d.release());
  return std::make_unique<VolumeRepresentation>(name, std::unique_ptr<render::VolumeDisplay>(v));
}

}  // namespace skel::gui
