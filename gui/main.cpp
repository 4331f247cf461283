// skelflow-gui [PIPELINE]: the node editor, properties, runs and 3D views over a pipeline YAML.
#include <QApplication>
#include <QCommandLineParser>
#include <QSurfaceFormat>
#include <QTimer>

#include <QVTKOpenGLNativeWidget.h>

#include <cstdio>

#include "main_window.hpp"
#include "skel/plugin.hpp"

int main(int argc, char** argv) {
  // VTK needs its OpenGL context format before the application exists.
  QSurfaceFormat::setDefaultFormat(QVTKOpenGLNativeWidget::defaultFormat());
  QApplication app(argc, argv);
  QApplication::setOrganizationName("skelflow");
  QApplication::setApplicationName("skelflow-gui");
  QApplication::setApplicationVersion("0.1.0");

  QCommandLineParser parser;
  parser.setApplicationDescription("Skelflow pipeline editor: build, run and view skeletonisation pipelines.");
  parser.addHelpOption();
  parser.addVersionOption();
  parser.addPositionalArgument("pipeline", "pipeline YAML to open (the format `skelflow run` reads)", "[PIPELINE]");
  QCommandLineOption run_option("run", "run the pipeline after opening it");
  parser.addOption(run_option);
  parser.process(app);

  // Plugin modules join the palette; a refused plugin is reported on stderr with its file and why.
  for (const auto& e : skel::load_plugins().errors) std::fprintf(stderr, "skelflow-gui: warning: %s\n", e.c_str());
  skel::gui::MainWindow window;
  const QStringList args = parser.positionalArguments();
  if (!args.isEmpty() && !window.open_file(args.front())) return 1;
  window.show();
  if (parser.isSet(run_option)) QTimer::singleShot(0, &window, [&window] { window.run_all(); });
  return QApplication::exec();
}
