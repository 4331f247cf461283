#pragma once
// A mesh in the 3D view (thesis §3.1.3, figs. 6.7-6.14): triangles as a surface, lines as lines or
// tubes, plain or coloured by any vertex, triangle or line attribute; by default by the triangles'
// `manifold` class (all-manifold / not-all-manifold) when the mesh has it.
#include <vtkSmartPointer.h>

#include "representation.hpp"
#include "skel/mesh.hpp"

class QComboBox;
class QDoubleSpinBox;
class vtkPolyData;

namespace skel::gui {

class MeshRepresentation final : public Representation {
public:
  MeshRepresentation(const QString& name, const std::shared_ptr<const Mesh>& mesh, const Color& color);
  ~MeshRepresentation() override;

  // "vertex:NAME", "triangle:NAME" or "line:NAME"; empty: plain colour.
  void set_color_by(const QString& attribute) { color_by_ = attribute; }
  [[nodiscard]] const QString& color_by() const { return color_by_; }
  void set_tubes(bool tubes) { tubes_ = tubes; }
  // The choices of set_color_by() for this mesh.
  [[nodiscard]] QStringList color_choices() const;

  [[nodiscard]] std::vector<vtkSmartPointer<vtkProp>> build_props(vtkScalarBarActor* bar) override;
  [[nodiscard]] bool uses_scalar_bar() const override { return !color_by_.isEmpty(); }
  [[nodiscard]] QWidget* create_controls() override;
  void update_controls() override;

protected:
  void keep_settings(const Representation& old) override;

private:
  std::shared_ptr<const Mesh> mesh_;
  vtkSmartPointer<vtkPolyData> surface_, lines_;
  QString color_by_;
  bool tubes_ = true;
  double tube_radius_ = 1.0;  // in the mesh's unit; set from its size

  QComboBox* color_box_ = nullptr;
  QComboBox* lines_box_ = nullptr;
  QDoubleSpinBox* radius_box_ = nullptr;
};

}  // namespace skel::gui
