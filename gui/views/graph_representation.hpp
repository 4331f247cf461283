#pragma once
// A spatial graph in the 3D view: lines or tubes (radius attribute x scale), plain or coloured by any
// point/edge attribute (the view's scalar bar shows the colours).
#include <vtkSmartPointer.h>

#include "representation.hpp"
#include "skel/spatial_graph.hpp"

class QComboBox;
class QDoubleSpinBox;
class vtkPolyData;

namespace skel::gui {

enum class GraphMode { Lines, Tubes };

class GraphRepresentation final : public Representation {
public:
  // Tubes coloured by radius when the graph has a radius attribute, else plain lines.
  GraphRepresentation(const QString& name, const std::shared_ptr<const SpatialGraph>& graph, const Color& color);
  ~GraphRepresentation() override;

  [[nodiscard]] GraphMode mode() const { return mode_; }
  void set_mode(GraphMode mode) { mode_ = mode; }
  void set_color_by(const QString& attribute) { color_by_ = attribute; }  // empty: plain colour

  [[nodiscard]] std::vector<vtkSmartPointer<vtkProp>> build_props(vtkScalarBarActor* bar) override;
  [[nodiscard]] bool uses_scalar_bar() const override { return !color_by_.isEmpty(); }
  [[nodiscard]] QWidget* create_controls() override;
  void update_controls() override;

protected:
  void keep_settings(const Representation& old) override;

private:
  std::shared_ptr<const SpatialGraph> graph_;
  vtkSmartPointer<vtkPolyData> poly_;
  GraphMode mode_ = GraphMode::Lines;
  QString color_by_;
  double tube_scale_ = 1.0;

  QComboBox* mode_box_ = nullptr;
  QComboBox* color_box_ = nullptr;
  QDoubleSpinBox* scale_box_ = nullptr;
};

}  // namespace skel::gui
