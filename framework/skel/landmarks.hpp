#pragma once
// LandmarkSet: one or more sets of the same number of named points in physical units (type id
// "landmarks"). Like Amira's LandmarkSet, corresponding sets live in one object: point i of set 0
// corresponds to point i of set 1 (and of every further set). By the registration convention set 0
// is the *fixed* (reference) set and set 1 the *moving* set.
//
// Storage (plain value semantics, public like SpatialGraph):
//   - names[i]: the name of point i (shared by all sets; "L1", "L2", ... when not given).
//   - sets[s][i]: position of point i in set s, in the physical unit `unit`.
#include <cstdint>
#include <string>
#include <vector>

#include "skel/data.hpp"
#include "skel/volume.hpp"

namespace skel {

class LandmarkSet final : public DataObject {
public:
  LandmarkSet() = default;
  // One set per entry of `sets`; all sets must have the same size (throws InputError otherwise).
  // Empty `names` gets the default names "L1".."Ln"; otherwise names.size() must equal the set size.
  explicit LandmarkSet(std::vector<std::vector<Vec3>> sets, std::vector<std::string> names = {});

  std::vector<std::string> names;       // names[i]: name of point i
  std::vector<std::vector<Vec3>> sets;  // sets[s][i]: point i of set s
  std::string unit{kDefaultUnit};       // physical unit of the coordinates (CSV: from the header "x [mm]")

  [[nodiscard]] int64_t set_count() const { return static_cast<int64_t>(sets.size()); }
  // Points per set (the size of names, which equals every set's size in a consistent object).
  [[nodiscard]] int64_t point_count() const { return static_cast<int64_t>(names.size()); }
  // Set s; throws InputError if s is out of range.
  [[nodiscard]] const std::vector<Vec3>& set(int64_t s) const;
  // Appends a set; throws InputError if its size differs from point_count() (a first set on an
  // empty object defines the count and gets default names).
  void add_set(std::vector<Vec3> points);
  // A LandmarkSet holding only set s of this one (same names).
  [[nodiscard]] LandmarkSet single_set(int64_t s) const;
  // The default name of point i: "L" + (i + 1).
  [[nodiscard]] static std::string default_name(int64_t i);
  // Problems found (empty = consistent): every set has names.size() points, coordinates finite.
  [[nodiscard]] std::vector<std::string> check_invariants() const;

  bool operator==(const LandmarkSet& o) const { return names == o.names && sets == o.sets && unit == o.unit; }

  // DataObject
  [[nodiscard]] std::string type_id() const override { return type_ids::landmarks; }
  [[nodiscard]] uint64_t bytes() const override;
  [[nodiscard]] std::string describe() const override;
  [[nodiscard]] std::string physical_unit() const override { return unit; }
};

}  // namespace skel
