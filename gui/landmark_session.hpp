#pragma once
// The model of the landmark mode (issue 9, thesis §6.2 "Analyzing Architectural Alterations"):
// numbered pairs of corresponding points, set 1 (fixed, LandmarkSet set 0) and set 2 (moving,
// LandmarkSet set 1), placed one point at a time, moved and deleted through a QUndoStack, with the
// residuals of a registration.landmarks fit (rigid by default) recomputed after every change.
// No VTK and no window: the 3D view's LandmarkMode drives it, tests drive it directly.
//
// As a QAbstractTableModel it is the residual table itself: one row per pair (number, set-1 point,
// set-2 point, residual |T(moving) - fixed|) and a last row "RMS" (the fit's RMS, or why there is
// no fit). Only complete pairs enter the fit; a pair missing one of its points shows "—".
#include <QAbstractTableModel>
#include <QString>
#include <QUndoStack>

#include <array>
#include <optional>
#include <vector>

#include "registration/registration.hpp"
#include "skel/landmarks.hpp"
#include "skel/transform.hpp"

namespace skel::gui {

class PipelineDocument;

// One numbered pair: p[0] in set 1 (fixed), p[1] in set 2 (moving); either may be missing while
// the pair is being placed.
struct LandmarkPair {
  std::array<std::optional<Vec3>, 2> p;
  [[nodiscard]] bool complete() const { return p[0].has_value() && p[1].has_value(); }
  bool operator==(const LandmarkPair& o) const { return p == o.p; }
};

class LandmarkSession final : public QAbstractTableModel {
  Q_OBJECT
public:
  enum Column { ColPair = 0, ColSet1, ColSet2, ColResidual, ColumnCount };

  explicit LandmarkSession(QObject* parent = nullptr);
  ~LandmarkSession() override;

  [[nodiscard]] const std::vector<LandmarkPair>& pairs() const { return pairs_; }
  [[nodiscard]] int pair_count() const { return static_cast<int>(pairs_.size()); }
  [[nodiscard]] int complete_count() const;
  [[nodiscard]] std::optional<Vec3> point(int pair, int set) const;
  [[nodiscard]] QUndoStack* undo_stack() { return &undo_; }

  // The set that add_point(p) fills: 0 (set 1, fixed) or 1 (set 2, moving). With `alternate` on
  // (the default) each placed point switches to the other set, so clicks go 1, 2, 1, 2, ...
  [[nodiscard]] int active_set() const { return active_; }
  void set_active_set(int set);
  [[nodiscard]] bool alternate() const { return alternate_; }
  void set_alternate(bool on) { alternate_ = on; }

  // ---- edits (each one undo step; false with message() emitted when not applicable)
  // Places p in the active set (then switches sets when alternating); returns the pair index.
  int add_point(const Vec3& p);
  // Places p in `set`: in the first pair that lacks a point of that set, else in a new pair.
  int add_point(int set, const Vec3& p);
  bool move_point(int pair, int set, const Vec3& p);
  bool delete_point(int pair, int set);  // a pair left without points is removed
  bool delete_pair(int pair);            // later pairs are renumbered
  bool clear_all();
  // Replaces every pair by the first two sets of `lm` (one set: set 1 only). One undo step.
  void set_landmarks(const LandmarkSet& lm, const QString& text = "Load landmarks");

  // ---- fit (recomputed after every change and model switch)
  [[nodiscard]] TransformKind model() const { return model_; }
  void set_model(TransformKind model);
  [[nodiscard]] bool has_fit() const { return fit_.has_value(); }
  [[nodiscard]] const registration::LandmarkFit* fit() const { return fit_ ? &*fit_ : nullptr; }
  // Why there is no fit (too few complete pairs, degenerate configuration), else empty.
  [[nodiscard]] const QString& fit_error() const { return fit_error_; }
  // |T(moving) - fixed| of a complete pair under the current fit; NaN without one.
  [[nodiscard]] double residual(int pair) const;
  [[nodiscard]] double rms() const;  // NaN without a fit

  // ---- files
  // Both sets when any set-2 point exists (then every pair must be complete), else set 1 alone.
  // Throws InputError naming the incomplete pair.
  [[nodiscard]] LandmarkSet landmark_set() const;
  // Writes landmark_set() (format by extension; .landmarkAscii = Amira). Marks the stack clean.
  void save(const QString& path);
  // Reads a landmark file (any format of registration/landmark_io.hpp) as one undo step.
  void load(const QString& path);
  // Adds `io.read_landmarks` (path = `file`, relative to the pipeline's folder when inside it) and,
  // when the file holds two sets, `registration.landmarks` (model = model()) fed by it, as one undo
  // macro of `doc`. Existing nodes for the same file are reused (the model is updated). Returns the
  // id of the read node. Throws skel::Error when the document refuses an edit.
  QString add_pipeline_nodes(PipelineDocument* doc, const QString& file) const;

  // ---- QAbstractTableModel
  int rowCount(const QModelIndex& parent = {}) const override;
  int columnCount(const QModelIndex& parent = {}) const override;
  QVariant data(const QModelIndex& index, int role = Qt::DisplayRole) const override;
  QVariant headerData(int section, Qt::Orientation orientation, int role = Qt::DisplayRole) const override;

  // Colours of the two sets (also used by the 3D view).
  static std::array<double, 3> set_color(int set);

  // Used by the undo command.
  void apply_state(const std::vector<LandmarkPair>& pairs);

signals:
  void landmarks_changed();  // pairs or fit changed
  void active_set_changed(int set);
  void message(const QString& text, bool error);

private:
  void push(const QString& text, std::vector<LandmarkPair> after);
  void refit();
  bool valid(int pair, int set, const char* what);

  std::vector<LandmarkPair> pairs_;
  QUndoStack undo_;
  int active_ = 0;
  bool alternate_ = true;
  TransformKind model_ = TransformKind::Rigid;
  std::optional<registration::LandmarkFit> fit_;
  std::vector<int> fit_index_;  // pair -> index into fit_->distance, -1 if not in the fit
  QString fit_error_;
};

}  // namespace skel::gui
