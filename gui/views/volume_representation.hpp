#pragma once
// A volume in the 3D view: its render::VolumeDisplay (slices with window/level, MIP, iso-surface,
// volume rendering or voxel surface, inside an outline of the grid) and the page that sets them.
#include "representation.hpp"

class QComboBox;
class QDoubleSpinBox;
class QSlider;

namespace skel::gui {

using render::VolumeMode;

class VolumeRepresentation final : public Representation {
public:
  VolumeRepresentation(const QString& name, std::unique_ptr<render::VolumeDisplay> display);
  ~VolumeRepresentation() override;

  [[nodiscard]] VolumeMode mode() const { return volume_->mode(); }
  void set_mode(VolumeMode mode) { volume_->set_mode(mode); }
  void set_window_level(double window, double level) { volume_->set_window_level(window, level); }
  void set_iso_value(double value) { volume_->set_iso_value(value); }

  [[nodiscard]] QWidget* create_controls() override;
  void update_controls() override;

private:
  render::VolumeDisplay* volume_;  // owned by the base

  QComboBox* mode_box_ = nullptr;
  QDoubleSpinBox* window_box_ = nullptr;
  QDoubleSpinBox* level_box_ = nullptr;
  QSlider* slice_box_[3] = {nullptr, nullptr, nullptr};
  QDoubleSpinBox* iso_box_ = nullptr;
};

}  // namespace skel::gui
