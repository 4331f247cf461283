#pragma once
// A mesh in the 3D view (thesis §3.1.3, figs. 6.7-6.14): its render::MeshDisplay (triangles as a
// surface, lines as lines or tubes, plain or coloured by any vertex, triangle or line attribute; by
// default by the triangles' `manifold` class) and the page that sets them.
#include <QStringList>

#include "representation.hpp"

class QComboBox;
class QDoubleSpinBox;

namespace skel::gui {

class MeshRepresentation final : public Representation {
public:
  MeshRepresentation(const QString& name, std::unique_ptr<render::MeshDisplay> display);
  ~MeshRepresentation() override;

  // "vertex:NAME", "triangle:NAME" or "line:NAME"; empty: plain colour.
  void set_color_by(const QString& attribute) { mesh_->set_color_by(attribute.toStdString()); }
  [[nodiscard]] QString color_by() const { return QString::fromStdString(mesh_->color_by()); }
  void set_tubes(bool tubes) { mesh_->set_tubes(tubes); }
  // The choices of set_color_by() for this mesh.
  [[nodiscard]] QStringList color_choices() const;

  [[nodiscard]] QWidget* create_controls() override;
  void update_controls() override;

private:
  render::MeshDisplay* mesh_;  // owned by the base

  QComboBox* color_box_ = nullptr;
  QComboBox* lines_box_ = nullptr;
  QDoubleSpinBox* radius_box_ = nullptr;
};

}  // namespace skel::gui
