#pragma once
// Runs the document's pipeline on a worker thread with the engine's Executor (which keeps every
// output in its cache for viewing) and publishes per-node states and overall progress on the UI
// thread. Snapshot (copy of the pipeline) -> compute off the UI thread -> publish (queued signals).
#include <QFutureWatcher>
#include <QHash>
#include <QObject>
#include <QString>
#include <QStringList>

#include <atomic>
#include <memory>

#include "skel/executor.hpp"

namespace skel::gui {

class PipelineDocument;

class RunController : public QObject {
  Q_OBJECT
public:
  explicit RunController(PipelineDocument* doc, QObject* parent = nullptr);
  ~RunController() override;  // cancels a running pipeline and waits for it

  [[nodiscard]] bool is_running() const { return running_; }
  // Starts a run of the whole pipeline (targets empty) or of what the targets need. Returns false
  // when a run is in progress; an invalid pipeline finishes at once with finished(false, reason).
  bool start(const QStringList& targets = {});
  void cancel();
  // Blocks until the current run (if any) is over; for tests and shutdown.
  void wait();

  [[nodiscard]] NodeStatus status(const QString& node) const { return status_.value(node); }
  [[nodiscard]] double progress() const { return progress_; }
  // Cached output of a node for the current pipeline (nullptr while running, stale or not computed).
  [[nodiscard]] DataPtr output(const QString& node, const QString& port) const;
  [[nodiscard]] RunReport last_report() const { return executor_.last_report(); }
  [[nodiscard]] Executor& executor() { return executor_; }
  void set_threads(int threads) { threads_ = threads; }
  // Folder relative output paths resolve against (empty: the pipeline file's folder, as the CLI).
  void set_output_dir(const QString& dir) { output_dir_ = dir; }

signals:
  void started();
  void node_status_changed(const QString& node);
  void progress_changed(double overall);
  void warning(const QString& node, const QString& message);
  void finished(bool ok, const QString& message);

private:
  struct Result {
    bool ok = false;
    QString message;
  };
  // Marks nodes whose cached results no longer match the pipeline as stale.
  void refresh_states(bool after_run);
  void on_finished();

  PipelineDocument* doc_;
  Executor executor_;
  QHash<QString, NodeStatus> status_;
  double progress_ = 0;
  bool running_ = false;
  int threads_ = 0;
  QString output_dir_;
  QFutureWatcher<Result> watcher_;
};

}  // namespace skel::gui
