#include "properties_panel.hpp"

#include <QCheckBox>
#include <QComboBox>
#include <QDoubleSpinBox>
#include <QFileDialog>
#include <QFormLayout>
#include <QHBoxLayout>
#include <QScrollArea>
#include <QSpinBox>
#include <QTimer>
#include <QToolButton>
#include <QVBoxLayout>

#include <climits>
#include <cmath>

#include "file_filters.hpp"
#include "skel/error.hpp"
#include "skel/units.hpp"

namespace skel::gui {

namespace {

QString qstr(const std::string& s) { return QString::fromStdString(s); }

QSpinBox* int_box(const ParamSpec& spec, int64_t value) {
  auto* box = new QSpinBox;
  const double lo = spec.min ? std::max(*spec.min, static_cast<double>(INT_MIN)) : INT_MIN;
  const double hi = spec.max ? std::min(*spec.max, static_cast<double>(INT_MAX)) : INT_MAX;
  box->setRange(static_cast<int>(std::ceil(lo)), static_cast<int>(std::floor(hi)));
  box->setValue(static_cast<int>(std::clamp<int64_t>(value, box->minimum(), box->maximum())));
  box->setKeyboardTracking(false);
  if (!spec.unit.empty()) box->setSuffix(" " + qstr(spec.unit));
  return box;
}

QDoubleSpinBox* float_box(const ParamSpec& spec, double value) {
  auto* box = new QDoubleSpinBox;
  box->setDecimals(6);
  box->setRange(spec.min ? *spec.min : -1e12, spec.max ? *spec.max : 1e12);
  box->setSingleStep(std::abs(value) >= 10 ? 1.0 : 0.1);
  box->setValue(value);
  box->setKeyboardTracking(false);
  if (!spec.unit.empty()) box->setSuffix(" " + qstr(spec.unit));
  return box;
}

QString describe(const ParamSpec& spec) {
  QString tip = "<b>" + qstr(spec.name) + "</b> (" + to_string(spec.type) + ")<br>" + qstr(spec.doc).toHtmlEscaped();
  if (spec.min || spec.max) {
    tip += QString("<br>range [%1, %2]")
               .arg(spec.min ? QString::number(*spec.min) : "-inf", spec.max ? QString::number(*spec.max) : "inf");
  }
  if (!spec.unit.empty()) tip += "<br>unit: " + qstr(spec.unit);
  if (!spec.choices.empty()) {
    QStringList c;
    for (const auto& s : spec.choices) c << qstr(s);
    tip += "<br>choices: " + c.join(", ");
  }
  tip += "<br>default: " + qstr(format_value(spec.default_value)).toHtmlEscaped();
  return tip;
}

}  // namespace

PropertiesPanel::PropertiesPanel(PipelineDocument* doc, QWidget* parent) : QWidget(parent), doc_(doc) {
  auto* outer = new QVBoxLayout(this);
  outer->setContentsMargins(4, 4, 4, 4);
  auto* scroll = new QScrollArea(this);
  scroll->setWidgetResizable(true);
  scroll->setFrameShape(QFrame::NoFrame);
  scroll->setHorizontalScrollBarPolicy(Qt::ScrollBarAlwaysOff);
  body_ = new QWidget;
  scroll->setWidget(body_);
  error_ = new QLabel(this);
  error_->setWordWrap(true);
  error_->setStyleSheet("color: #e05050;");
  outer->addWidget(scroll, 1);
  outer->addWidget(error_);
  new QVBoxLayout(body_);
  connect(doc_, &PipelineDocument::param_changed, this, [this](const QString& id) {
    if (id == node_ && !applying_) rebuild();
  });
  connect(doc_, &PipelineDocument::graph_changed, this, [this] {
    if (!node_.isEmpty() && !doc_->has_node(node_)) node_.clear();
    rebuild();
  });
  connect(doc_, &PipelineDocument::document_reset, this, [this] { show_node({}); });
  rebuild();
}

void PropertiesPanel::show_node(const QString& id) {
  node_ = id;
  error_->clear();
  rebuild();
}

void PropertiesPanel::show_error(const QString& text) {
  error_->setText(text);
  if (!text.isEmpty()) emit message(text);
}

void PropertiesPanel::update_marks(const QString& param) {
  const PipelineNode* node = doc_->pipeline().find(node_.toStdString());
  if (!node) return;
  const ModuleSpec* spec = doc_->registry().find(node->module);
  const ParamSpec* ps = spec ? spec->find_param(param.toStdString()) : nullptr;
  if (!ps) return;
  const bool explicit_value = node->params.count(ps->name) > 0;
  if (QLabel* l = labels_.value(param)) l->setText(explicit_value ? "<b>" + param + "</b>" : param);
  if (QToolButton* r = resets_.value(param)) r->setEnabled(explicit_value);
}

void PropertiesPanel::rebuild() {
  editors_.clear();
  labels_.clear();
  resets_.clear();
  // Replace the whole body: cheap, and it drops every connection of the old editors.
  QLayout* old = body_->layout();
  while (QLayoutItem* item = old->takeAt(0)) {
    if (item->widget()) item->widget()->deleteLater();
    delete item;
  }
  auto* content = new QWidget;
  old->addWidget(content);
  static_cast<QVBoxLayout*>(old)->addStretch(1);
  auto* form = new QFormLayout(content);
  form->setFieldGrowthPolicy(QFormLayout::AllNonFixedFieldsGrow);
  form->setRowWrapPolicy(QFormLayout::WrapLongRows);

  const PipelineNode* node = node_.isEmpty() ? nullptr : doc_->pipeline().find(node_.toStdString());
  if (!node) {
    auto* hint = new QLabel("Select a node to edit its parameters.");
    hint->setWordWrap(true);
    form->addRow(hint);
    return;
  }
  const ModuleSpec* spec = doc_->registry().find(node->module);
  auto* id_edit = new QLineEdit(node_);
  id_edit->setToolTip("node id (letters, digits, '_')");
  connect(id_edit, &QLineEdit::editingFinished, this, [this, id_edit] {
    const QString new_id = id_edit->text().trimmed();
    if (new_id == node_) return;
    const QString old_id = node_;
    node_ = new_id;  // follow the rename
    const QString err = doc_->rename_node(old_id, new_id);
    if (!err.isEmpty()) {
      node_ = old_id;
      show_error(err);
      QTimer::singleShot(0, this, [this] { rebuild(); });
    }
  });
  form->addRow("<b>id</b>", id_edit);
  auto* module = new QLabel("<b>" + qstr(node->module) + "</b><br>" +
                            (spec ? qstr(spec->doc()).toHtmlEscaped() : QString("unknown module")));
  module->setWordWrap(true);
  module->setTextFormat(Qt::RichText);
  form->addRow(module);
  if (!spec) return;
  const ParamMap values = effective_params(*node, *spec);
  const std::string input_unit = input_unit_ ? input_unit_(node_) : std::string();
  for (ParamSpec ps : spec->params()) {
    // A length in the input's unit shows that unit once it is known.
    if (!input_unit.empty()) {
      if (ps.unit == units::length) ps.unit = input_unit;
      else if (ps.unit == units::area) ps.unit = units::power(input_unit, 2);
      else if (ps.unit == units::volume) ps.unit = units::power(input_unit, 3);
    }
    const QString name = qstr(ps.name);
    const bool explicit_value = node->params.count(ps.name) > 0;
    auto it = values.find(ps.name);
    const ParamValue value = it != values.end() ? it->second : ps.default_value;
    QWidget* editor = make_editor(ps, value);
    editor->setToolTip(describe(ps));
    editors_.insert(name, editor);
    auto* row = new QWidget;
    auto* h = new QHBoxLayout(row);
    h->setContentsMargins(0, 0, 0, 0);
    h->addWidget(editor, 1);
    auto* reset = new QToolButton;
    reset->setText("↺");
    reset->setToolTip("reset to the default (" + qstr(format_value(ps.default_value)) + ")");
    reset->setEnabled(explicit_value);
    resets_.insert(name, reset);
    connect(reset, &QToolButton::clicked, this, [this, name] { doc_->reset_param(node_, name); });
    h->addWidget(reset);
    auto* label = new QLabel(explicit_value ? "<b>" + name + "</b>" : name);
    label->setToolTip(describe(ps));
    labels_.insert(name, label);
    form->addRow(label, row);
  }
}

QWidget* PropertiesPanel::make_editor(const ParamSpec& ps, const ParamValue& value) {
  const QString name = qstr(ps.name);
  switch (ps.type) {
    case ParamType::Bool: {
      auto* box = new QCheckBox;
      box->setChecked(std::holds_alternative<bool>(value) && std::get<bool>(value));
      connect(box, &QCheckBox::toggled, this, [this, name](bool on) { apply(name, ParamValue(on)); });
      return box;
    }
    case ParamType::Int: {
      auto* box = int_box(ps, std::holds_alternative<int64_t>(value) ? std::get<int64_t>(value) : 0);
      connect(box, qOverload<int>(&QSpinBox::valueChanged), this,
              [this, name](int v) { apply(name, ParamValue(static_cast<int64_t>(v))); });
      return box;
    }
    case ParamType::Float: {
      auto* box = float_box(ps, std::holds_alternative<double>(value) ? std::get<double>(value) : 0.0);
      connect(box, qOverload<double>(&QDoubleSpinBox::valueChanged), this,
              [this, name](double v) { apply(name, ParamValue(v)); });
      return box;
    }
    case ParamType::Choice: {
      auto* box = new QComboBox;
      for (const auto& c : ps.choices) box->addItem(qstr(c));
      if (auto* s = std::get_if<std::string>(&value)) box->setCurrentText(qstr(*s));
      connect(box, qOverload<int>(&QComboBox::activated), this,
              [this, name, box](int) { apply(name, ParamValue(box->currentText().toStdString())); });
      return box;
    }
    case ParamType::String:
    case ParamType::Path: {
      auto* edit = new QLineEdit;
      if (auto* s = std::get_if<std::string>(&value)) edit->setText(qstr(*s));
      connect(edit, &QLineEdit::editingFinished, this,
              [this, name, edit] { apply(name, ParamValue(edit->text().toStdString())); });
      if (ps.type == ParamType::String) return edit;
      auto* w = new QWidget;
      auto* h = new QHBoxLayout(w);
      h->setContentsMargins(0, 0, 0, 0);
      h->addWidget(edit, 1);
      auto* browse = new QToolButton;
      browse->setText("…");
      browse->setToolTip(ps.path_role == PathRole::Output ? "choose a file to write" : "choose a file to read");
      const bool output = ps.path_role == PathRole::Output;
      const QString filter = file_dialog_filter(ps);  // from the readers' and writers' extensions
      connect(browse, &QToolButton::clicked, this, [this, name, edit, output, filter] {
        const QString base = QString::fromStdString(doc_->pipeline().base_dir().string());
        const QString path = output ? QFileDialog::getSaveFileName(this, "Output file", base, filter)
                                    : QFileDialog::getOpenFileName(this, "Input file", base, filter);
        if (path.isEmpty()) return;
        edit->setText(path);
        apply(name, ParamValue(path.toStdString()));
      });
      h->addWidget(browse);
      return w;
    }
    case ParamType::IntList:
    case ParamType::FloatList: {
      const bool ints = ps.type == ParamType::IntList;
      if (ps.list_length >= 1 && ps.list_length <= 4) {
        // One spin box per component: sizes, spacing, voxel positions.
        auto* w = new QWidget;
        auto* h = new QHBoxLayout(w);
        h->setContentsMargins(0, 0, 0, 0);
        h->setSpacing(2);
        std::vector<QAbstractSpinBox*> boxes;
        ParamSpec element = ps;
        element.unit.clear();  // the unit goes once, after the last field
        for (int i = 0; i < ps.list_length; ++i) {
          if (ints) {
            const auto* v = std::get_if<std::vector<int64_t>>(&value);
            auto* box = int_box(element, v && static_cast<int>(v->size()) > i ? (*v)[i] : 0);
            boxes.push_back(box);
            h->addWidget(box, 1);
          } else {
            const auto* v = std::get_if<std::vector<double>>(&value);
            auto* box = float_box(element, v && static_cast<int>(v->size()) > i ? (*v)[i] : 0.0);
            box->setDecimals(4);
            boxes.push_back(box);
            h->addWidget(box, 1);
          }
        }
        if (!ps.unit.empty()) h->addWidget(new QLabel(qstr(ps.unit)));
        auto on_change = [this, name, boxes, ints] {
          if (ints) {
            std::vector<int64_t> v;
            for (auto* b : boxes) v.push_back(static_cast<QSpinBox*>(b)->value());
            apply(name, ParamValue(v));
          } else {
            std::vector<double> v;
            for (auto* b : boxes) v.push_back(static_cast<QDoubleSpinBox*>(b)->value());
            apply(name, ParamValue(v));
          }
        };
        for (auto* b : boxes) {
          if (ints) {
            connect(static_cast<QSpinBox*>(b), qOverload<int>(&QSpinBox::valueChanged), this, on_change);
          } else {
            connect(static_cast<QDoubleSpinBox*>(b), qOverload<double>(&QDoubleSpinBox::valueChanged), this, on_change);
          }
        }
        return w;
      }
      // Any length: typed as a YAML list, checked against the spec.
      auto* edit = new QLineEdit(qstr(format_value(value)));
      edit->setPlaceholderText(ints ? "[1, 2, 3]" : "[0.5, 1.0]");
      connect(edit, &QLineEdit::editingFinished, this, [this, name, edit] {
        try {
          apply(name, parse_param_text(edit->text().toStdString()));
        } catch (const Error& e) {
          show_error(name + ": " + QString::fromStdString(e.what()));
          QTimer::singleShot(0, this, [this] { rebuild(); });
        }
      });
      return edit;
    }
  }
  return new QLabel("?");
}

void PropertiesPanel::apply(const QString& param, const ParamValue& value) {
  if (node_.isEmpty()) return;
  applying_ = true;
  const QString err = doc_->set_param(node_, param, value);
  applying_ = false;
  if (!err.isEmpty()) {
    show_error(err);
    // Restore the editor to the document's value after the current signal has returned.
    QTimer::singleShot(0, this, [this] { rebuild(); });
  } else {
    error_->clear();
    update_marks(param);
  }
}

}  // namespace skel::gui
