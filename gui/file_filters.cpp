#include "file_filters.hpp"

#include <QStringList>

#include <algorithm>

#include "io/volume_format.hpp"

namespace skel::gui {

namespace {

// "*.tif *.TIF": the extensions are lower case and match any case when a pipeline runs, but the
// dialogs' filters follow the file system's case (sensitive on Linux), so upper case is listed too.
QString patterns(const std::vector<std::string>& extensions) {
  QStringList p;
  for (const auto& e : extensions) p << "*" + QString::fromStdString(e);
  for (const auto& e : extensions)
    if (QString u = "*" + QString::fromStdString(e).toUpper(); !p.contains(u)) p << u;
  return p.join(' ');
}

}  // namespace

QString file_dialog_filter(const ParamSpec& param) {
  const auto& exts = param.extensions;
  if (exts.empty()) return "All files (*)";
  QStringList filters;
  filters << "Supported files (" + patterns(exts) + ")";
  // One entry per volume format the parameter takes, named as the registry names it.
  for (const auto& f : io::volume_formats()) {
    std::vector<std::string> mine;
    for (const auto& e : f.extensions)
      if (std::find(exts.begin(), exts.end(), e) != exts.end()) mine.push_back(e);
    if (!mine.empty()) filters << QString::fromStdString(f.name) + " (" + patterns(mine) + ")";
  }
  filters << "All files (*)";
  return filters.join(";;");
}

}  // namespace skel::gui
