#include "landmark_session.hpp"

#include <QBrush>
#include <QColor>
#include <QDir>
#include <QFileInfo>
#include <QPointF>
#include <QUndoCommand>

#include <algorithm>
#include <cmath>
#include <limits>

#include "io/landmark_io.hpp"
#include "io/names.hpp"
#include "pipeline_document.hpp"
#include "registration/names.hpp"
#include "skel/error.hpp"

using namespace skel::io;

namespace skel::gui {

namespace {
std::string str(const QString& s) { return s.toStdString(); }
QString qstr(const std::string& s) { return QString::fromStdString(s); }
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

QString format_point(const Vec3& p) {
  return QString("%1, %2, %3").arg(p[0], 0, 'f', 2).arg(p[1], 0, 'f', 2).arg(p[2], 0, 'f', 2);
}

// One landmark edit: the pairs before and after (a handful of points, so snapshots are cheap and
// undo is exact).
class LandmarkCommand final : public QUndoCommand {
public:
  LandmarkCommand(LandmarkSession* s, const QString& text, std::vector<LandmarkPair> before,
                  std::vector<LandmarkPair> after)
      : QUndoCommand(text), s_(s), before_(std::move(before)), after_(std::move(after)) {}
  void redo() override { s_->apply_state(after_); }
  void undo() override { s_->apply_state(before_); }

private:
  LandmarkSession* s_;
  std::vector<LandmarkPair> before_, after_;
};
}  // namespace

LandmarkSession::LandmarkSession(QObject* parent) : QAbstractTableModel(parent) { refit(); }

LandmarkSession::~LandmarkSession() { undo_.clear(); }

std::array<double, 3> LandmarkSession::set_color(int set) {
  return set == 0 ? std::array<double, 3>{1.0, 0.62, 0.12} : std::array<double, 3>{0.2, 0.85, 1.0};
}

int LandmarkSession::complete_count() const {
  return static_cast<int>(std::count_if(pairs_.begin(), pairs_.end(), [](const auto& p) { return p.complete(); }));
}

std::optional<Vec3> LandmarkSession::point(int pair, int set) const {
  if (pair < 0 || pair >= pair_count() || set < 0 || set > 1) return std::nullopt;
  return pairs_[static_cast<size_t>(pair)].p[static_cast<size_t>(set)];
}

void LandmarkSession::set_active_set(int set) {
  set = set == 0 ? 0 : 1;
  if (set == active_) return;
  active_ = set;
  emit active_set_changed(active_);
}

bool LandmarkSession::valid(int pair, int set, const char* what) {
  if (pair >= 0 && pair < pair_count() && set >= 0 && set <= 1 && pairs_[static_cast<size_t>(pair)].p[static_cast<size_t>(set)])
    return true;
  emit message(QString("%1: pair %2 has no point in set %3").arg(what).arg(pair + 1).arg(set + 1), true);
  return false;
}

void LandmarkSession::push(const QString& text, std::vector<LandmarkPair> after) {
  undo_.push(new LandmarkCommand(this, text, pairs_, std::move(after)));
}

void LandmarkSession::apply_state(const std::vector<LandmarkPair>& pairs) {
  beginResetModel();
  pairs_ = pairs;
  refit();
  endResetModel();
  emit landmarks_changed();
}

int LandmarkSession::add_point(const Vec3& p) {
  const int set = active_;
  const int pair = add_point(set, p);
  if (pair >= 0 && alternate_) set_active_set(1 - set);
  return pair;
}

int LandmarkSession::add_point(int set, const Vec3& p) {
  if (set < 0 || set > 1 || !std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
    emit message("Add landmark: invalid set or position", true);
    return -1;
  }
  std::vector<LandmarkPair> after = pairs_;
  const auto s = static_cast<size_t>(set);
  auto it = std::find_if(after.begin(), after.end(), [&](const LandmarkPair& q) { return !q.p[s]; });
  if (it == after.end()) it = after.insert(after.end(), LandmarkPair{});
  it->p[s] = p;
  const int pair = static_cast<int>(it - after.begin());
  push(QString("Place %1 of set %2 at [%3]").arg(pair + 1).arg(set + 1).arg(format_point(p)), std::move(after));
  return pair;
}

bool LandmarkSession::move_point(int pair, int set, const Vec3& p) {
  if (!valid(pair, set, "Move landmark")) return false;
  if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) return false;
  std::vector<LandmarkPair> after = pairs_;
  after[static_cast<size_t>(pair)].p[static_cast<size_t>(set)] = p;
  push(QString("Move %1 of set %2 to [%3]").arg(pair + 1).arg(set + 1).arg(format_point(p)), std::move(after));
  return true;
}

bool LandmarkSession::delete_point(int pair, int set) {
  if (!valid(pair, set, "Delete landmark")) return false;
  std::vector<LandmarkPair> after = pairs_;
  auto& q = after[static_cast<size_t>(pair)];
  q.p[static_cast<size_t>(set)].reset();
  if (!q.p[0] && !q.p[1]) after.erase(after.begin() + pair);
  push(QString("Delete %1 of set %2").arg(pair + 1).arg(set + 1), std::move(after));
  return true;
}

bool LandmarkSession::delete_pair(int pair) {
  if (pair < 0 || pair >= pair_count()) {
    emit message(QString("Delete pair: no pair %1").arg(pair + 1), true);
    return false;
  }
  std::vector<LandmarkPair> after = pairs_;
  after.erase(after.begin() + pair);
  push(QString("Delete pair %1").arg(pair + 1), std::move(after));
  return true;
}

bool LandmarkSession::clear_all() {
  if (pairs_.empty()) return false;
  push("Delete all landmarks", {});
  return true;
}

void LandmarkSession::set_landmarks(const LandmarkSet& lm, const QString& text) {
  std::vector<LandmarkPair> after(static_cast<size_t>(lm.point_count()));
  for (int64_t s = 0; s < std::min<int64_t>(2, lm.set_count()); ++s) {
    const auto& pts = lm.set(s);
    for (size_t i = 0; i < after.size() && i < pts.size(); ++i) after[i].p[static_cast<size_t>(s)] = pts[i];
  }
  if (lm.set_count() > 2)
    emit message(QString("%1: the object holds %2 sets; sets 1 and 2 are used").arg(text).arg(lm.set_count()), false);
  push(text, std::move(after));
}

void LandmarkSession::set_model(TransformKind model) {
  if (model == model_) return;
  beginResetModel();
  model_ = model;
  refit();
  endResetModel();
  emit landmarks_changed();
}

void LandmarkSession::refit() {
  fit_.reset();
  fit_error_.clear();
  fit_index_.assign(pairs_.size(), -1);
  std::vector<Vec3> fixed, moving;
  for (size_t i = 0; i < pairs_.size(); ++i) {
    if (!pairs_[i].complete()) continue;
    fit_index_[i] = static_cast<int>(fixed.size());
    fixed.push_back(*pairs_[i].p[0]);
    moving.push_back(*pairs_[i].p[1]);
  }
  const size_t needed = model_ == TransformKind::Affine ? 4 : 3;
  if (fixed.size() < needed) {
    fit_error_ = QString("a %1 fit needs %2 complete pairs (have %3)")
                     .arg(qstr(to_string(model_)))
                     .arg(needed)
                     .arg(fixed.size());
    return;
  }
  try {
    fit_ = registration::fit_landmarks(fixed, moving, model_, "landmark pairs");
  } catch (const std::exception& e) {
    fit_error_ = QString::fromUtf8(e.what());
  }
}

double LandmarkSession::residual(int pair) const {
  if (!fit_ || pair < 0 || pair >= pair_count() || fit_index_[static_cast<size_t>(pair)] < 0) return kNaN;
  return fit_->distance[static_cast<size_t>(fit_index_[static_cast<size_t>(pair)])];
}

double LandmarkSession::rms() const { return fit_ ? fit_->rms : kNaN; }

// ---------------------------------------------------------------- files
LandmarkSet LandmarkSession::landmark_set() const {
  if (pairs_.empty()) throw InputError("no landmarks placed");
  const bool two = std::any_of(pairs_.begin(), pairs_.end(), [](const auto& p) { return p.p[1].has_value(); });
  std::vector<std::vector<Vec3>> sets(two ? 2 : 1);
  for (size_t i = 0; i < pairs_.size(); ++i) {
    for (size_t s = 0; s < sets.size(); ++s) {
      if (!pairs_[i].p[s]) {
        throw InputError("pair " + std::to_string(i + 1) + " has no point in set " + std::to_string(s + 1) +
                         "; place it or delete the pair");
      }
      sets[s].push_back(*pairs_[i].p[s]);
    }
  }
  return LandmarkSet(std::move(sets));
}

void LandmarkSession::save(const QString& path) {
  io::write_landmarks(str(path), landmark_set());
  undo_.setClean();
}

void LandmarkSession::load(const QString& path) {
  const LandmarkSet lm = io::read_landmarks(str(path));
  if (lm.set_count() == 0 || lm.point_count() == 0) throw InputError(str(path) + ": holds no landmarks");
  set_landmarks(lm, "Load " + QDir::toNativeSeparators(path));
  undo_.setClean();
}

QString LandmarkSession::add_pipeline_nodes(PipelineDocument* doc, const QString& file) const {
  QString path = QFileInfo(file).absoluteFilePath();
  const QString base = qstr(doc->pipeline().base_dir().string());
  if (!doc->file_path().isEmpty() && !base.isEmpty()) {
    const QString rel = QDir(base).relativeFilePath(path);
    if (!rel.startsWith("..")) path = rel;
  }
  const bool two = landmark_set().set_count() >= 2;
  // Reuse the nodes of an earlier save of the same file.
  QString read_id, fit_id;
  for (const auto& n : doc->pipeline().nodes()) {
    auto p = n.params.find("path");
    if (n.module == io::names::read_landmarks && p != n.params.end() && std::holds_alternative<std::string>(p->second) &&
        qstr(std::get<std::string>(p->second)) == path)
      read_id = qstr(n.id);
  }
  if (!read_id.isEmpty()) {
    for (const auto& n : doc->pipeline().nodes()) {
      auto in = n.inputs.find("landmarks");
      if (n.module == registration::names::landmarks && in != n.inputs.end() && qstr(in->second.node) == read_id)
        fit_id = qstr(n.id);
    }
  }
  // The model of an existing fit node (unset = the module's default, rigid).
  QString fit_model = "rigid";
  if (const PipelineNode* n = fit_id.isEmpty() ? nullptr : doc->pipeline().find(str(fit_id))) {
    auto m = n->params.find("model");
    if (m != n->params.end() && std::holds_alternative<std::string>(m->second)) fit_model = qstr(std::get<std::string>(m->second));
  }
  const QString model = qstr(to_string(model_));
  if (!read_id.isEmpty() && (!two || (!fit_id.isEmpty() && fit_model == model))) return read_id;  // nothing to change
  QStringList problems;
  auto check = [&](const QString& e) {
    if (!e.isEmpty()) problems << e;
  };
  // Right of the existing nodes.
  QPointF at(0, 0);
  bool first = true;
  for (const QPointF& p : doc->positions()) {
    at = first ? p : QPointF(std::max(at.x(), p.x()), std::min(at.y(), p.y()));
    first = false;
  }
  if (!first) at += QPointF(260, 0);
  QUndoStack* stack = doc->undo_stack();
  stack->beginMacro("Add landmark nodes for " + path);
  QString error;
  if (read_id.isEmpty()) {
    read_id = doc->add_node(io::names::read_landmarks, at, &error);
    if (read_id.isEmpty()) {
      stack->endMacro();
      throw Error(std::string("adding ") + io::names::read_landmarks + ": " + str(error));
    }
    check(doc->set_param(read_id, "path", ParamValue(str(path))));
  }
  if (two) {
    if (fit_id.isEmpty()) {
      fit_id = doc->add_node(registration::names::landmarks, doc->position(read_id) + QPointF(260, 0), &error);
      if (fit_id.isEmpty()) problems << "adding " + QString(registration::names::landmarks) + ": " + error;
      else check(doc->connect_ports(read_id, "landmarks", fit_id, "landmarks"));
    }
    if (!fit_id.isEmpty() && fit_model != model) check(doc->set_param(fit_id, "model", ParamValue(str(model))));
  }
  stack->endMacro();
  if (!problems.isEmpty()) throw Error("adding the landmark nodes: " + str(problems.join("; ")));
  return read_id;
}

// ---------------------------------------------------------------- table model
int LandmarkSession::rowCount(const QModelIndex& parent) const {
  return parent.isValid() || pairs_.empty() ? 0 : pair_count() + 1;
}

int LandmarkSession::columnCount(const QModelIndex& parent) const { return parent.isValid() ? 0 : ColumnCount; }

QVariant LandmarkSession::headerData(int section, Qt::Orientation orientation, int role) const {
  if (orientation != Qt::Horizontal || role != Qt::DisplayRole) return {};
  switch (section) {
    case ColPair: return "#";
    case ColSet1: return "Set 1 (fixed)";
    case ColSet2: return "Set 2 (moving)";
    case ColResidual: return "Residual";
    default: return {};
  }
}

QVariant LandmarkSession::data(const QModelIndex& index, int role) const {
  if (!index.isValid() || index.row() < 0 || index.row() > pair_count()) return {};
  const int row = index.row(), col = index.column();
  if (row == pair_count()) {  // the RMS row
    if (role == Qt::DisplayRole) {
      if (col == ColPair) return "RMS";
      if (col == ColResidual) return fit_ ? QString::number(fit_->rms, 'g', 4) : QString("—");
      if (col == ColSet1) return fit_ ? QString("%1 fit of %2 pairs").arg(qstr(to_string(model_))).arg(fit_->distance.size())
                                      : fit_error_;
    }
    if (role == Qt::ToolTipRole) return fit_ ? QString::fromStdString(fit_->transform.describe()) : fit_error_;
    return {};
  }
  const LandmarkPair& p = pairs_[static_cast<size_t>(row)];
  if (role == Qt::DisplayRole) {
    switch (col) {
      case ColPair: return row + 1;
      case ColSet1:
      case ColSet2: {
        const auto& q = p.p[static_cast<size_t>(col - ColSet1)];
        return q ? format_point(*q) : QString("—");
      }
      case ColResidual: {
        const double r = residual(row);
        return std::isnan(r) ? QString("—") : QString::number(r, 'g', 4);
      }
      default: return {};
    }
  }
  if (role == Qt::DecorationRole && (col == ColSet1 || col == ColSet2)) {
    const auto c = set_color(col - ColSet1);
    return QColor::fromRgbF(c[0], c[1], c[2]);
  }
  if (role == Qt::TextAlignmentRole && col == ColResidual) return int(Qt::AlignRight | Qt::AlignVCenter);
  return {};
}

}  // namespace skel::gui
