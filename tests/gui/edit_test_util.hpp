#pragma once
// Shared by the edit-mode test and its crash helper: a small variant of pipelines/vessel_network.yaml
// (80×80×56 phantom instead of 160×160×112, same modules and parameters) written into `dir`.
#include <QDir>
#include <QFile>
#include <QRegularExpression>
#include <QString>
#include <QTextStream>

inline QString write_small_vessel_pipeline(const QString& dir) {
  QFile in(QString(SKEL_SOURCE_DIR) + "/pipelines/vessel_network.yaml");
  if (!in.open(QIODevice::ReadOnly)) return {};
  QString text = QString::fromUtf8(in.readAll());
  text.replace(QRegularExpression("size: \\[160, 160, 112\\]"), "size: [80, 80, 56]");
  const QString path = QDir(dir).filePath("vessel_small.yaml");
  QFile out(path);
  if (!out.open(QIODevice::WriteOnly)) return {};
  out.write(text.toUtf8());
  return path;
}
