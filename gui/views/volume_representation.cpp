#include "volume_representation.hpp"

#include <QComboBox>
#include <QDoubleSpinBox>
#include <QFormLayout>
#include <QSlider>
#include <QWidget>

#include <algorithm>

namespace skel::gui {

VolumeRepresentation::VolumeRepresentation(const QString& name, std::unique_ptr<render::VolumeDisplay> display)
    : Representation(name, std::move(display)), volume_(static_cast<render::VolumeDisplay*>(&this->display())) {}

VolumeRepresentation::~VolumeRepresentation() = default;

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
    volume_->set_mode(static_cast<VolumeMode>(i));
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
      volume_->set_slice(k, v);
      if (volume_->mode() == VolumeMode::Slices) changed();
    });
  }
  QObject::connect(iso_box_, qOverload<double>(&QDoubleSpinBox::valueChanged), page, [this](double v) {
    if (syncing_) return;
    volume_->set_iso_value(v);
    changed();
  });
  return page;
}

void VolumeRepresentation::update_controls() {
  if (!mode_box_) return;
  syncing_ = true;
  const double window = volume_->window();
  const int* extent = volume_->extent();
  const double* range = volume_->range();
  mode_box_->setCurrentIndex(static_cast<int>(volume_->mode()));
  window_box_->setValue(window);
  level_box_->setValue(volume_->level());
  window_box_->setSingleStep(std::max(window / 50, 1e-4));
  level_box_->setSingleStep(std::max(window / 50, 1e-4));
  for (int k = 0; k < 3; ++k) {
    slice_box_[k]->setRange(extent[2 * k], extent[2 * k + 1]);
    slice_box_[k]->setValue(volume_->slice(k));
  }
  iso_box_->setValue(volume_->iso_value());
  iso_box_->setSingleStep(std::max((range[1] - range[0]) / 50, 1e-4));
  syncing_ = false;
}

}  // namespace skel::gui
