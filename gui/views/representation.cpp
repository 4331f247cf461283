#include "representation.hpp"

#include <vtkProp.h>

#include "graph_representation.hpp"
#include "mesh_representation.hpp"
#include "volume_representation.hpp"

namespace skel::gui {

Representation::Representation(QString name, DataPtr data, const Color& color)
    : name_(std::move(name)), data_(std::move(data)), color_(color) {}

Representation::~Representation() = default;

void Representation::keep_display_of(const Representation& old) {
  color_ = old.color_;
  visible_ = old.visible_;
  keep_settings(old);
}

std::unique_ptr<Representation> make_representation(const QString& name, const DataPtr& data, const Color& color,
                                                    QString* error) {
  if (auto g = std::dynamic_pointer_cast<const SpatialGraph>(data)) return std::make_unique<GraphRepresentation>(name, g, color);
  if (auto m = std::dynamic_pointer_cast<const Mesh>(data)) return std::make_unique<MeshRepresentation>(name, m, color);
  if (auto v = VolumeRepresentation::create(name, data, color)) return v;
  if (error) *error = name + ": the 3D view shows volumes, graphs and meshes, not " + QString::fromStdString(data->type_id());
  return nullptr;
}

}  // namespace skel::gui
