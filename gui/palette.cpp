#include "palette.hpp"

#include <QHeaderView>
#include <QMimeData>
#include <QVBoxLayout>

#include "node_editor.hpp"

namespace skel::gui {

namespace {
constexpr int kModuleRole = Qt::UserRole + 1;

QString port_list(const std::vector<PortSpec>& ports) {
  QStringList parts;
  for (const auto& p : ports) parts << QString::fromStdString(p.name) + " (" + port_type_label(p) + ")";
  return parts.isEmpty() ? QString("—") : parts.join(", ");
}
}  // namespace

QStringList ModuleTree::mimeTypes() const { return {kModuleMime}; }

QMimeData* ModuleTree::mimeData(const QList<QTreeWidgetItem*> items) const {
  if (items.isEmpty()) return nullptr;
  const QString module = items.front()->data(0, kModuleRole).toString();
  if (module.isEmpty()) return nullptr;
  auto* mime = new QMimeData;
  mime->setData(kModuleMime, module.toUtf8());
  mime->setText(module);
  return mime;
}

Palette::Palette(const Registry& registry, QWidget* parent) : QWidget(parent) {
  search_ = new QLineEdit(this);
  search_->setPlaceholderText("Search modules…");
  search_->setClearButtonEnabled(true);
  tree_ = new ModuleTree(this);
  tree_->setHeaderHidden(true);
  tree_->setDragEnabled(true);
  tree_->setDragDropMode(QAbstractItemView::DragOnly);
  tree_->setSelectionMode(QAbstractItemView::SingleSelection);
  auto* layout = new QVBoxLayout(this);
  layout->setContentsMargins(2, 2, 2, 2);
  layout->addWidget(search_);
  layout->addWidget(tree_);

  QMap<QString, QTreeWidgetItem*> families;
  for (const ModuleSpec* spec : registry.specs()) {
    const QString family = QString::fromStdString(spec->family());
    QTreeWidgetItem*& fam = families[family];
    if (!fam) {
      fam = new QTreeWidgetItem(tree_, {family});
      fam->setFlags(Qt::ItemIsEnabled);
      QFont f = fam->font(0);
      f.setBold(true);
      fam->setFont(0, f);
    }
    const QString name = QString::fromStdString(spec->name());
    auto* item = new QTreeWidgetItem(fam, {name.mid(name.indexOf('.') + 1)});
    item->setData(0, kModuleRole, name);
    item->setFlags(Qt::ItemIsEnabled | Qt::ItemIsSelectable | Qt::ItemIsDragEnabled);
    item->setToolTip(0, QString("<b>%1</b><br>%2<br><br><i>inputs:</i> %3<br><i>outputs:</i> %4")
                            .arg(name, QString::fromStdString(spec->doc()).toHtmlEscaped(),
                                 port_list(spec->inputs()), port_list(spec->outputs())));
  }
  tree_->expandAll();
  connect(search_, &QLineEdit::textChanged, this, &Palette::set_filter);
  connect(tree_, &QTreeWidget::itemActivated, this, [this](QTreeWidgetItem* item) {
    const QString module = item->data(0, kModuleRole).toString();
    if (!module.isEmpty()) emit module_activated(module);
  });
}

void Palette::set_filter(const QString& text) {
  if (search_->text() != text) search_->setText(text);
  for (int i = 0; i < tree_->topLevelItemCount(); ++i) {
    QTreeWidgetItem* fam = tree_->topLevelItem(i);
    int shown = 0;
    for (int j = 0; j < fam->childCount(); ++j) {
      QTreeWidgetItem* item = fam->child(j);
      const bool match = text.isEmpty() || item->data(0, kModuleRole).toString().contains(text, Qt::CaseInsensitive) ||
                         item->toolTip(0).contains(text, Qt::CaseInsensitive);
      item->setHidden(!match);
      shown += match;
    }
    fam->setHidden(shown == 0);
  }
}

QStringList Palette::visible_modules() const {
  QStringList out;
  for (int i = 0; i < tree_->topLevelItemCount(); ++i) {
    QTreeWidgetItem* fam = tree_->topLevelItem(i);
    for (int j = 0; j < fam->childCount(); ++j) {
      if (!fam->isHidden() && !fam->child(j)->isHidden()) out << fam->child(j)->data(0, kModuleRole).toString();
    }
  }
  return out;
}

}  // namespace skel::gui
