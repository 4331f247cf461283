#pragma once
// A volume in the 3D view, inside a thin outline of its grid: three orthogonal slices with
// window/level, maximum-intensity projection, iso-surface, volume rendering, or voxel surface (the
// default for binary masks and skeletons).
#include <vtkSmartPointer.h>

#include <cmath>

#include "representation.hpp"

class QComboBox;
class QDoubleSpinBox;
class QSlider;
class vtkActor;
class vtkImageData;

namespace skel::gui {

enum class VolumeMode { Slices, Mip, IsoSurface, VolumeRendering, VoxelSurface };

class VolumeRepresentation final : public Representation {
public:
  // Null if `data` is not a volume.
  static std::unique_ptr<VolumeRepresentation> create(const QString& name, const DataPtr& data, const Color& color);
  ~VolumeRepresentation() override;

  [[nodiscard]] VolumeMode mode() const { return mode_; }
  void set_mode(VolumeMode mode) { mode_ = mode; }
  void set_window_level(double window, double level);
  void set_iso_value(double value) { iso_ = value; }

  [[nodiscard]] std::vector<vtkSmartPointer<vtkProp>> build_props(vtkScalarBarActor* bar) override;
  [[nodiscard]] QWidget* create_controls() override;
  void update_controls() override;

protected:
  void keep_settings(const Representation& old) override;

private:
  VolumeRepresentation(const QString& name, const DataPtr& data, const Color& color,
                       vtkSmartPointer<vtkImageData> image);

  vtkSmartPointer<vtkImageData> image_;
  bool binary_ = false;
  double range_[2] = {0, 1};
  int extent_[6] = {0, 0, 0, 0, 0, 0};
  VolumeMode mode_ = VolumeMode::Slices;
  double window_ = 1, level_ = 0.5, iso_ = 0.5;
  int slice_[3] = {0, 0, 0};
  vtkSmartPointer<vtkActor> outline_;
  // Surfaces are costly to extract: kept while their inputs stay the same.
  vtkSmartPointer<vtkActor> surface_;
  double surface_iso_ = std::nan("");
  vtkSmartPointer<vtkActor> voxels_;

  QComboBox* mode_box_ = nullptr;
  QDoubleSpinBox* window_box_ = nullptr;
  QDoubleSpinBox* level_box_ = nullptr;
  QSlider* slice_box_[3] = {nullptr, nullptr, nullptr};
  QDoubleSpinBox* iso_box_ = nullptr;
};

}  // namespace skel::gui
