#include "mesh_representation.hpp"

#include <QComboBox>
#include <QDoubleSpinBox>
#include <QFormLayout>
#include <QWidget>

namespace skel::gui {

MeshRepresentation::MeshRepresentation(const QString& name, std::unique_ptr<render::MeshDisplay> display)
    : Representation(name, std::move(display)), mesh_(static_cast<render::MeshDisplay*>(&this->display())) {}

MeshRepresentation::~MeshRepresentation() = default;

QStringList MeshRepresentation::color_choices() const {
  QStringList out;
  for (const auto& c : mesh_->color_choices()) out << QString::fromStdString(c);
  return out;
}

QWidget* MeshRepresentation::create_controls() {
  auto* page = new QWidget;
  auto* form = new QFormLayout(page);
  color_box_ = new QComboBox;
  form->addRow("Colour by", color_box_);
  lines_box_ = new QComboBox;
  lines_box_->addItems({"Lines", "Tubes"});
  form->addRow("Lines as", lines_box_);
  radius_box_ = new QDoubleSpinBox;
  radius_box_->setRange(1e-4, 1e6);
  radius_box_->setDecimals(4);
  radius_box_->setKeyboardTracking(false);
  form->addRow("Tube radius", radius_box_);
  QObject::connect(color_box_, qOverload<int>(&QComboBox::activated), page, [this](int i) {
    mesh_->set_color_by(i == 0 ? std::string() : color_box_->itemText(i).toStdString());
    changed();
  });
  QObject::connect(lines_box_, qOverload<int>(&QComboBox::activated), page, [this](int i) {
    mesh_->set_tubes(i == 1);
    changed();
  });
  QObject::connect(radius_box_, qOverload<double>(&QDoubleSpinBox::valueChanged), page, [this](double v) {
    if (syncing_) return;
    mesh_->set_tube_radius(v);
    changed();
  });
  return page;
}

void MeshRepresentation::update_controls() {
  if (!color_box_) return;
  syncing_ = true;
  color_box_->clear();
  color_box_->addItem("(plain colour)");
  int index = 0;
  for (const QString& c : color_choices()) {
    color_box_->addItem(c);
    if (c == color_by()) index = color_box_->count() - 1;
  }
  color_box_->setCurrentIndex(index);
  lines_box_->setCurrentIndex(mesh_->tubes() ? 1 : 0);
  radius_box_->setValue(mesh_->tube_radius());
  syncing_ = false;
}

}  // namespace skel::gui
