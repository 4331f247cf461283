#include "graph_representation.hpp"

#include <QComboBox>
#include <QDoubleSpinBox>
#include <QFormLayout>
#include <QWidget>

namespace skel::gui {

GraphRepresentation::GraphRepresentation(const QString& name, std::unique_ptr<render::GraphDisplay> display)
    : Representation(name, std::move(display)), graph_(static_cast<render::GraphDisplay*>(&this->display())) {}

GraphRepresentation::~GraphRepresentation() = default;

QWidget* GraphRepresentation::create_controls() {
  auto* page = new QWidget;
  auto* form = new QFormLayout(page);
  mode_box_ = new QComboBox;
  mode_box_->addItems({"Lines", "Tubes (radius)"});
  form->addRow("Display", mode_box_);
  color_box_ = new QComboBox;
  form->addRow("Colour by", color_box_);
  scale_box_ = new QDoubleSpinBox;
  scale_box_->setRange(0.01, 100);
  scale_box_->setValue(1.0);
  scale_box_->setSingleStep(0.1);
  scale_box_->setKeyboardTracking(false);
  form->addRow("Radius scale", scale_box_);

  QObject::connect(mode_box_, qOverload<int>(&QComboBox::activated), page, [this](int i) {
    graph_->set_mode(static_cast<GraphMode>(i));
    changed();
  });
  QObject::connect(color_box_, qOverload<int>(&QComboBox::activated), page, [this](int i) {
    graph_->set_color_by(i == 0 ? std::string() : color_box_->itemText(i).toStdString());
    changed();
  });
  QObject::connect(scale_box_, qOverload<double>(&QDoubleSpinBox::valueChanged), page, [this](double v) {
    if (syncing_) return;
    graph_->set_tube_scale(v);
    changed();
  });
  return page;
}

void GraphRepresentation::update_controls() {
  if (!mode_box_) return;
  syncing_ = true;
  mode_box_->setCurrentIndex(static_cast<int>(graph_->mode()));
  color_box_->clear();
  color_box_->addItem("(plain colour)");
  int index = 0;
  for (const auto& n : graph_->color_choices()) {
    color_box_->addItem(QString::fromStdString(n));
    if (n == graph_->color_by()) index = color_box_->count() - 1;
  }
  color_box_->setCurrentIndex(index);
  scale_box_->setValue(graph_->tube_scale());
  syncing_ = false;
}

}  // namespace skel::gui
