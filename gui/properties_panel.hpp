#pragma once
// Properties panel generated from a module's ParamSpecs: spin boxes with ranges and units, combo
// boxes for choices, check boxes, file pickers for paths and one field per component for short
// vectors (sizes, spacing). Values outside the spec are refused at entry (ranges of the spin boxes,
// the spec's check for typed text) and every accepted change is one undoable document command.
#include <QLabel>
#include <QLineEdit>
#include <QMap>
#include <QPointer>
#include <QWidget>

#include <functional>
#include <string>

#include "pipeline_document.hpp"

class QFormLayout;
class QToolButton;

namespace skel::gui {

class PropertiesPanel final : public QWidget {
  Q_OBJECT
public:
  explicit PropertiesPanel(PipelineDocument* doc, QWidget* parent = nullptr);
  void show_node(const QString& id);  // empty: nothing selected
  [[nodiscard]] const QString& node() const { return node_; }
  // The editor widget of a parameter (tests drive it like a user would).
  [[nodiscard]] QWidget* editor(const QString& param) const { return editors_.value(param); }
  [[nodiscard]] QString error_text() const { return error_->text(); }
  // The physical unit of a node's input data when known (after a run; "" otherwise): parameters in
  // the input's unit (units::length, area, volume) then show it ("mm") instead of "input unit".
  void set_input_unit_source(std::function<std::string(const QString& node)> source) {
    input_unit_ = std::move(source);
  }
  void refresh() { rebuild(); }

signals:
  void message(const QString& text);

private:
  void rebuild();
  QWidget* make_editor(const ParamSpec& spec, const ParamValue& value);
  // Sends a value to the document; on refusal shows the reason and restores the editor.
  void apply(const QString& param, const ParamValue& value);
  void show_error(const QString& text);
  void update_marks(const QString& param);  // bold label and reset button of an explicit value

  PipelineDocument* doc_;
  QString node_;
  QWidget* body_ = nullptr;
  QLabel* error_;
  QMap<QString, QWidget*> editors_;
  QMap<QString, QLabel*> labels_;
  QMap<QString, QToolButton*> resets_;
  bool applying_ = false;
  std::function<std::string(const QString& node)> input_unit_;
};

}  // namespace skel::gui
