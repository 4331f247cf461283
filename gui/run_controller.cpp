#include "run_controller.hpp"

#include <QMetaObject>
#include <QtConcurrent/QtConcurrentRun>

#include "pipeline_document.hpp"
#include "skel/error.hpp"

namespace skel::gui {

RunController::RunController(PipelineDocument* doc, QObject* parent) : QObject(parent), doc_(doc) {
  connect(&watcher_, &QFutureWatcher<Result>::finished, this, &RunController::on_finished);
  connect(doc_, &PipelineDocument::graph_changed, this, [this] { refresh_states(false); });
  connect(doc_, &PipelineDocument::param_changed, this, [this] { refresh_states(false); });
  connect(doc_, &PipelineDocument::document_reset, this, [this] {
    status_.clear();
    refresh_states(false);
  });
}

RunController::~RunController() {
  cancel();
  wait();
}

bool RunController::start(const QStringList& targets) {
  if (running_) return false;
  ExecOptions options;
  options.threads = threads_;
  options.keep_outputs = true;
  if (!output_dir_.isEmpty()) options.output_dir = output_dir_.toStdString();
  for (const QString& t : targets) options.targets.push_back(t.toStdString());
  // Callbacks come from worker threads: hand them to the UI thread (dropped if this object dies).
  options.on_status = [this](const std::string& node, const NodeStatus& s) {
    QMetaObject::invokeMethod(
        this,
        [this, id = QString::fromStdString(node), s] {
          status_[id] = s;
          emit node_status_changed(id);
        },
        Qt::QueuedConnection);
  };
  options.on_progress = [this](double overall) {
    QMetaObject::invokeMethod(
        this,
        [this, overall] {
          progress_ = overall;
          emit progress_changed(overall);
        },
        Qt::QueuedConnection);
  };
  options.on_warning = [this](const std::string& node, const std::string& message) {
    QMetaObject::invokeMethod(
        this,
        [this, n = QString::fromStdString(node), m = QString::fromStdString(message)] { emit warning(n, m); },
        Qt::QueuedConnection);
  };

  // Nodes that will run show as waiting at once; the executor reports the rest.
  Pipeline snapshot = doc_->pipeline();
  std::set<std::string> needed;
  try {
    needed = snapshot.upstream_closure(options.targets);
  } catch (const Error&) {
  }
  for (const auto& id : needed) {
    NodeStatus& s = status_[QString::fromStdString(id)];
    if (s.state != NodeState::Done && s.state != NodeState::Cached) {
      s = NodeStatus{NodeState::Waiting, 0.0, {}};
      emit node_status_changed(QString::fromStdString(id));
    }
  }

  running_ = true;
  progress_ = 0;
  emit started();
  emit progress_changed(0);
  watcher_.setFuture(QtConcurrent::run([this, p = std::move(snapshot), options]() -> Result {
    try {
      RunReport r = executor_.run(p, options);
      return {r.ok, r.ok ? QString("done in %1 s").arg(r.seconds, 0, 'f', 2) : QString::fromStdString(r.error)};
    } catch (const Cancelled&) {
      return {false, "cancelled"};
    } catch (const std::exception& e) {
      return {false, QString::fromStdString(e.what())};
    }
  }));
  return true;
}

void RunController::cancel() {
  if (running_) executor_.cancel();
}

void RunController::wait() {
  if (running_) watcher_.waitForFinished();
}

void RunController::on_finished() {
  const Result r = watcher_.result();
  running_ = false;
  if (r.ok) progress_ = 1.0;
  refresh_states(true);
  emit progress_changed(progress_);
  emit finished(r.ok, r.message);
}

DataPtr RunController::output(const QString& node, const QString& port) const {
  if (running_) return nullptr;
  return executor_.output(doc_->pipeline(), node.toStdString(), port.toStdString());
}

void RunController::refresh_states(bool after_run) {
  if (running_) return;
  std::set<std::string> fresh;
  try {
    fresh = executor_.up_to_date(doc_->pipeline());
  } catch (const std::exception&) {
    // An invalid graph (e.g. a module missing) has no fresh results.
  }
  QHash<QString, NodeStatus> next;
  for (const QString& id : doc_->node_ids()) {
    NodeStatus s = status_.value(id);
    const bool is_fresh = fresh.count(id.toStdString()) > 0;
    if (is_fresh) {
      if (s.state != NodeState::Done && s.state != NodeState::Cached) s = NodeStatus{NodeState::Done, 1.0, {}};
    } else if (s.state == NodeState::Idle) {
      // never ran: stays idle
    } else if (after_run && (s.state == NodeState::Error || s.state == NodeState::Cancelled)) {
      // keep the message of the run that just ended
    } else if (after_run && s.state == NodeState::Waiting) {
      s = NodeStatus{NodeState::Idle, 0.0, {}};
    } else {
      s = NodeStatus{NodeState::Stale, 0.0, s.state == NodeState::Error ? s.message : std::string()};
    }
    const bool changed = !status_.contains(id) || status_.value(id).state != s.state ||
                         status_.value(id).message != s.message;
    next.insert(id, s);
    if (changed) {
      status_.insert(id, s);
      emit node_status_changed(id);
    }
  }
  status_ = next;
}

}  // namespace skel::gui
