#pragma once
// A spatial graph in the 3D view: its render::GraphDisplay (lines or tubes, plain or coloured by any
// point/edge attribute; the view's scalar bar shows the colours) and the page that sets them.
#include "representation.hpp"

class QComboBox;
class QDoubleSpinBox;

namespace skel::gui {

using render::GraphMode;

class GraphRepresentation final : public Representation {
public:
  GraphRepresentation(const QString& name, std::unique_ptr<render::GraphDisplay> display);
  ~GraphRepresentation() override;

  [[nodiscard]] GraphMode mode() const { return graph_->mode(); }
  void set_mode(GraphMode mode) { graph_->set_mode(mode); }
  void set_color_by(const QString& attribute) { graph_->set_color_by(attribute.toStdString()); }  // empty: plain

  [[nodiscard]] QWidget* create_controls() override;
  void update_controls() override;

private:
  render::GraphDisplay* graph_;  // owned by the base

  QComboBox* mode_box_ = nullptr;
  QComboBox* color_box_ = nullptr;
  QDoubleSpinBox* scale_box_ = nullptr;
};

}  // namespace skel::gui
