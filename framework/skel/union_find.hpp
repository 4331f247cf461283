#pragma once
// Disjoint sets over the ids 0..n-1 (union-find), shared by every family that groups elements:
// graph components, junction collapse, run-based connected components, matching components.
//
// A union links the larger root under the smaller one, so the root of a set is always its smallest
// id: whatever the order of the unions (or how they are split between threads working on disjoint
// id ranges), the roots are the same, and anything numbered by them is deterministic. Finds split
// the path (every node on it is pointed at its grandparent), which keeps trees flat without a rank
// array; together with the smallest-id rule, parent(i) <= i holds for every i, so one forward pass
// over the ids resolves every id to its root (see flatten()).
#include <cstdint>
#include <numeric>
#include <utility>
#include <vector>

namespace skel {

class UnionFind {
public:
  UnionFind() = default;
  explicit UnionFind(int64_t n) : parent_(static_cast<size_t>(n)) {
    std::iota(parent_.begin(), parent_.end(), int64_t{0});
  }

  [[nodiscard]] int64_t size() const { return static_cast<int64_t>(parent_.size()); }

  // The root (smallest id) of x's set.
  int64_t find(int64_t x) {
    int64_t* p = parent_.data();
    while (p[x] != x) {
      const int64_t up = p[x];
      p[x] = p[up];
      x = up;
    }
    return x;
  }

  // Merges the sets of a and b; true when they were different sets.
  bool unite(int64_t a, int64_t b) {
    a = find(a);
    b = find(b);
    if (a == b) return false;
    if (a < b) parent_[static_cast<size_t>(b)] = a;
    else parent_[static_cast<size_t>(a)] = b;
    return true;
  }

  // Points every id straight at its root, in one forward pass (parent(i) <= i).
  void flatten() {
    int64_t* p = parent_.data();
    for (int64_t i = 0, n = size(); i < n; ++i) p[i] = p[p[i]];
  }

  // parent(i) for every i: the roots after flatten().
  [[nodiscard]] const std::vector<int64_t>& parents() const { return parent_; }
  // Hands the parent array over (e.g. to keep it as a run -> root map) and leaves this empty.
  [[nodiscard]] std::vector<int64_t> release() && { return std::move(parent_); }

private:
  std::vector<int64_t> parent_;
};

}  // namespace skel
