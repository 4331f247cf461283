#pragma once
// Progress reporting and cancellation for long algorithms: a cheap value passed by const reference
// that defaults to a no-op (OpenVDB's "interrupter"). Algorithms call `check(f)` every few million
// voxels, never per voxel.
#include <atomic>
#include <functional>
#include <memory>
#include <string>

namespace skel {

class Interrupter {
public:
  using ReportFn = std::function<void(double)>;  // fraction in [0, 1]

  Interrupter() = default;  // no progress, never cancelled
  using NoteFn = std::function<void(const std::string&)>;  // a short status text
  Interrupter(ReportFn report, const std::atomic<bool>* cancel_flag, NoteFn note = {})
      : report_(std::make_shared<ReportFn>(std::move(report))), cancel_(cancel_flag),
        note_(note ? std::make_shared<NoteFn>(std::move(note)) : nullptr) {}

  // True once cancellation was requested.
  [[nodiscard]] bool cancelled() const {
    return cancel_ != nullptr && cancel_->load(std::memory_order_relaxed);
  }
  // Reports progress (fraction of this interrupter's range) and throws skel::Cancelled when asked to
  // stop. Thread-safe as long as the report function is.
  void check(double fraction) const;
  void check() const;  // cancellation only
  void report(double fraction) const;
  // Reports a short status text ("chamfer 37/512 blocks") where the runner shows one.
  void note(const std::string& text) const;

  // A view onto the sub-range [begin, end] of this interrupter's progress range, for multi-phase
  // algorithms (phase 1 = 0..0.3, phase 2 = 0.3..1).
  [[nodiscard]] Interrupter sub(double begin, double end) const;

private:
  std::shared_ptr<ReportFn> report_;
  const std::atomic<bool>* cancel_ = nullptr;
  std::shared_ptr<NoteFn> note_;
  double begin_ = 0.0, end_ = 1.0;
};

}  // namespace skel
