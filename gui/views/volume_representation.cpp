#include "volume_representation.hpp"

#include <QComboBox>
#include <QDoubleSpinBox>
#include <QFormLayout>
#include <QSlider>
#include <QWidget>

#include <vtkActor.h>
#include <vtkCellData.h>
#include <vtkColorTransferFunction.h>
#include <vtkFlyingEdges3D.h>
#include <vtkGeometryFilter.h>
#include <vtkImageActor.h>
#include <vtkImageData.h>
#include <vtkImageMapper3D.h>
#include <vtkImageProperty.h>
#include <vtkOutlineFilter.h>
#include <vtkPiecewiseFunction.h>
#include <vtkPolyDataMapper.h>
#include <vtkProperty.h>
#include <vtkSmartVolumeMapper.h>
#include <vtkThreshold.h>
#include <vtkVolume.h>
#include <vtkVolumeProperty.h>

#include <algorithm>
#include <cmath>

#include "vtk_convert.hpp"

namespace skel::gui {

std::unique_ptr<VolumeRepresentation> VolumeRepresentation::create(const QString& name, const DataPtr& data,
                                                                   const Color& color) {
  vtkSmartPointer<vtkImageData> image;
  try {
    image = volume_to_image(*data);
  } catch (const std::exception&) {
    return nullptr;  // not a volume
  }
  return std::unique_ptr<VolumeRepresentation>(new VolumeRepresentation(name, data, color, std::move(image)));
}

VolumeRepresentation::VolumeRepresentation(const QString& name, const DataPtr& data, const Color& color,
                                           vtkSmartPointer<vtkImageData> image)
    : Representation(name, data, color), image_(std::move(image)) {
  binary_ = is_binary_volume(*data);
  image_->GetScalarRange(range_);
  image_->GetExtent(extent_);
  for (int k = 0; k < 3; ++k) slice_[k] = (extent_[2 * k] + extent_[2 * k + 1]) / 2;
  window_ = std::max(range_[1] - range_[0], 1e-9);
  level_ = 0.5 * (range_[0] + range_[1]);
  iso_ = binary_ ? 0.5 : range_[0] + 0.5 * (range_[1] - range_[0]);
  mode_ = binary_ ? VolumeMode::VoxelSurface : VolumeMode::Slices;
  // A thin outline of the grid so slices and surfaces have context.
  auto outline = vtkSmartPointer<vtkOutlineFilter>::New();
  outline->SetInputData(image_);
  auto om = vtkSmartPointer<vtkPolyDataMapper>::New();
  om->SetInputConnection(outline->GetOutputPort());
  outline_ = vtkSmartPointer<vtkActor>::New();
  outline_->SetMapper(om);
  outline_->GetProperty()->SetColor(0.6, 0.6, 0.65);
}

VolumeRepresentation::~VolumeRepresentation() = default;

void VolumeRepresentation::keep_settings(const Representation& old) {
  const auto* v = dynamic_cast<const VolumeRepresentation*>(&old);
  if (!v || v->binary_ != binary_) return;
  mode_ = v->mode_;
  // Window, level, iso value and slices mean the same only for the same voxel type.
  if (v->data()->type_id() != data()->type_id()) return;
  window_ = v->window_;
  level_ = v->level_;
  iso_ = v->iso_;
  for (int k = 0; k < 3; ++k) slice_[k] = std::clamp(v->slice_[k], extent_[2 * k], extent_[2 * k + 1]);
}

void VolumeRepresentation::set_window_level(double window, double level) {
  window_ = std::max(window, 1e-12);
  level_ = level;
}

std::vector<vtkSmartPointer<vtkProp>> VolumeRepresentation::build_props(vtkScalarBarActor* /*bar*/) {
  std::vector<vtkSmartPointer<vtkProp>> props{outline_};
  switch (mode_) {
    case VolumeMode::Slices: {
      for (int k = 0; k < 3; ++k) {
        auto actor = vtkSmartPointer<vtkImageActor>::New();
        actor->GetMapper()->SetInputData(image_);
        int e[6];
        std::copy(std::begin(extent_), std::end(extent_), e);
        e[2 * k] = e[2 * k + 1] = std::clamp(slice_[k], extent_[2 * k], extent_[2 * k + 1]);
        actor->SetDisplayExtent(e);
        actor->GetProperty()->SetColorWindow(window_);
        actor->GetProperty()->SetColorLevel(level_);
        actor->GetProperty()->SetInterpolationTypeToNearest();
        props.push_back(actor);
      }
      break;
    }
    case VolumeMode::Mip:
    case VolumeMode::VolumeRendering: {
      auto mapper = vtkSmartPointer<vtkSmartVolumeMapper>::New();
      mapper->SetInputData(image_);
      const bool mip = mode_ == VolumeMode::Mip;
      if (mip) mapper->SetBlendModeToMaximumIntensity();
      else mapper->SetBlendModeToComposite();
      const double lo = level_ - 0.5 * window_, hi = level_ + 0.5 * window_;
      auto color = vtkSmartPointer<vtkColorTransferFunction>::New();
      auto opacity = vtkSmartPointer<vtkPiecewiseFunction>::New();
      if (mip) {
        color->AddRGBPoint(lo, 0, 0, 0);
        color->AddRGBPoint(hi, 1, 1, 1);
        opacity->AddPoint(lo, 0.0);
        opacity->AddPoint(hi, 1.0);
      } else {
        color->AddRGBPoint(lo, 0.2, 0.1, 0.05);
        color->AddRGBPoint(lo + 0.5 * (hi - lo), 0.9, 0.5, 0.2);
        color->AddRGBPoint(hi, 1.0, 1.0, 0.9);
        opacity->AddPoint(lo, 0.0);
        opacity->AddPoint(hi, 0.6);
      }
      auto prop = vtkSmartPointer<vtkVolumeProperty>::New();
      prop->SetColor(color);
      prop->SetScalarOpacity(opacity);
      prop->SetInterpolationTypeToLinear();
      if (!mip) prop->ShadeOn();
      auto volume = vtkSmartPointer<vtkVolume>::New();
      volume->SetMapper(mapper);
      volume->SetProperty(prop);
      props.push_back(volume);
      break;
    }
    case VolumeMode::IsoSurface: {
      if (!surface_ || surface_iso_ != iso_) {
        auto fe = vtkSmartPointer<vtkFlyingEdges3D>::New();
        fe->SetInputData(image_);
        fe->SetValue(0, iso_);
        fe->ComputeNormalsOn();
        fe->ComputeScalarsOff();
        auto m = vtkSmartPointer<vtkPolyDataMapper>::New();
        m->SetInputConnection(fe->GetOutputPort());
        m->ScalarVisibilityOff();
        surface_ = vtkSmartPointer<vtkActor>::New();
        surface_->SetMapper(m);
        surface_->GetProperty()->SetColor(color()[0], color()[1], color()[2]);
        surface_iso_ = iso_;
      }
      props.push_back(surface_);
      break;
    }
    case VolumeMode::VoxelSurface: {
      if (!voxels_) {
        // Each voxel >= iso is a cube; the outer faces of the kept cubes are the voxel surface.
        auto cells = volume_to_cell_image(*data());
        auto th = vtkSmartPointer<vtkThreshold>::New();
        th->SetInputData(cells);
        th->SetInputArrayToProcess(0, 0, 0, vtkDataObject::FIELD_ASSOCIATION_CELLS, "voxels");
        th->SetLowerThreshold(binary_ ? 0.5 : iso_);
        th->SetUpperThreshold(VTK_DOUBLE_MAX);
        th->SetThresholdFunction(vtkThreshold::THRESHOLD_BETWEEN);
        auto geom = vtkSmartPointer<vtkGeometryFilter>::New();
        geom->SetInputConnection(th->GetOutputPort());
        auto m = vtkSmartPointer<vtkPolyDataMapper>::New();
        m->SetInputConnection(geom->GetOutputPort());
        m->ScalarVisibilityOff();
        voxels_ = vtkSmartPointer<vtkActor>::New();
        voxels_->SetMapper(m);
        voxels_->GetProperty()->SetColor(color()[0], color()[1], color()[2]);
      }
      props.push_back(voxels_);
      break;
    }
  }
  return props;
}

QWidget* VolumeRepresentation::create_controls() {
  auto* page = new QWidget;
  auto* form = new QFormLayout(page);
  mode_box_ = new QComboBox;
  mode_box_->addItems({"Slices", "MIP", "Iso-surface", "Volume rendering", "Voxel surface"});
  form->addRow("Display", mode_box_);
  window_box_ = new QDoubleSpinBox;
  level_box_ = new QDoubleSpinBox;
  for (QDoubleSpinBox* b : {window_box_, level_box_}) {
    b->setRange(-1e12, 1e12);
    b->setDecimals(4);
    b->setKeyboardTracking(false);
  }
  form->addRow("Window", window_box_);
  form->addRow("Level", level_box_);
  const char* axes[3] = {"Slice x", "Slice y", "Slice z"};
  for (int k = 0; k < 3; ++k) {
    slice_box_[k] = new QSlider(Qt::Horizontal);
    form->addRow(axes[k], slice_box_[k]);
  }
  iso_box_ = new QDoubleSpinBox;
  iso_box_->setRange(-1e12, 1e12);
  iso_box_->setDecimals(4);
  iso_box_->setKeyboardTracking(false);
  form->addRow("Iso value", iso_box_);

  QObject::connect(mode_box_, qOverload<int>(&QComboBox::activated), page, [this](int i) {
    mode_ = static_cast<VolumeMode>(i);
    changed();
    update_controls();
  });
  auto wl = [this] {
    if (syncing_) return;
    set_window_level(window_box_->value(), level_box_->value());
    changed();
  };
  QObject::connect(window_box_, qOverload<double>(&QDoubleSpinBox::valueChanged), page, wl);
  QObject::connect(level_box_, qOverload<double>(&QDoubleSpinBox::valueChanged), page, wl);
  for (int k = 0; k < 3; ++k) {
    QObject::connect(slice_box_[k], &QSlider::valueChanged, page, [this, k](int v) {
      if (syncing_) return;
      slice_[k] = v;
      if (mode_ == VolumeMode::Slices) changed();
    });
  }
  QObject::connect(iso_box_, qOverload<double>(&QDoubleSpinBox::valueChanged), page, [this](double v) {
    if (syncing_) return;
    iso_ = v;
    changed();
  });
  return page;
}

void VolumeRepresentation::update_controls() {
  if (!mode_box_) return;
  syncing_ = true;
  mode_box_->setCurrentIndex(static_cast<int>(mode_));
  window_box_->setValue(window_);
  level_box_->setValue(level_);
  window_box_->setSingleStep(std::max(window_ / 50, 1e-4));
  level_box_->setSingleStep(std::max(window_ / 50, 1e-4));
  for (int k = 0; k < 3; ++k) {
    slice_box_[k]->setRange(extent_[2 * k], extent_[2 * k + 1]);
    slice_box_[k]->setValue(slice_[k]);
  }
  iso_box_->setValue(iso_);
  iso_box_->setSingleStep(std::max((range_[1] - range_[0]) / 50, 1e-4));
  syncing_ = false;
}

}  // namespace skel::gui
