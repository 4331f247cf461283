#pragma once
// Module palette: every registered module grouped by family, filtered by a search field, with the
// module's doc and ports as tooltip. Items are dragged onto the node editor (or double-clicked).
#include <QLineEdit>
#include <QTreeWidget>
#include <QWidget>

#include "skel/module.hpp"

namespace skel::gui {

class ModuleTree final : public QTreeWidget {
  Q_OBJECT
public:
  using QTreeWidget::QTreeWidget;

protected:
  [[nodiscard]] QStringList mimeTypes() const override;
  [[nodiscard]] QMimeData* mimeData(const QList<QTreeWidgetItem*> items) const override;
};

class Palette final : public QWidget {
  Q_OBJECT
public:
  explicit Palette(const Registry& registry, QWidget* parent = nullptr);
  // Shows only modules whose name or doc contains `text` (case-insensitive).
  void set_filter(const QString& text);
  [[nodiscard]] QStringList visible_modules() const;

signals:
  void module_activated(const QString& module);  // double click / Enter

private:
  QLineEdit* search_;
  ModuleTree* tree_;
};

}  // namespace skel::gui
