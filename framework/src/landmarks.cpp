#include "skel/landmarks.hpp"

#include <cmath>
#include <sstream>

#include "skel/error.hpp"

namespace skel {

LandmarkSet::LandmarkSet(std::vector<std::vector<Vec3>> s, std::vector<std::string> n) {
  const size_t count = s.empty() ? n.size() : s.front().size();
  for (size_t k = 0; k < s.size(); ++k) {
    if (s[k].size() != count) {
      throw InputError("landmarks: set " + std::to_string(k) + " has " + std::to_string(s[k].size()) +
                       " points; expected " + std::to_string(count) + " like set 0");
    }
  }
  if (!n.empty() && n.size() != count) {
    throw InputError("landmarks: " + std::to_string(n.size()) + " names for " + std::to_string(count) +
                     " points per set");
  }
  if (n.empty()) {
    n.reserve(count);
    for (size_t i = 0; i < count; ++i) n.push_back(default_name(static_cast<int64_t>(i)));
  }
  names = std::move(n);
  sets = std::move(s);
}

const std::vector<Vec3>& LandmarkSet::set(int64_t s) const {
  if (s < 0 || s >= set_count()) {
    throw InputError("landmarks: set " + std::to_string(s) + " requested, but the object has " +
                     std::to_string(set_count()) + " set(s)");
  }
  return sets[static_cast<size_t>(s)];
}

void LandmarkSet::add_set(std::vector<Vec3> points) {
  if (sets.empty() && names.empty()) {
    for (size_t i = 0; i < points.size(); ++i) names.push_back(default_name(static_cast<int64_t>(i)));
  }
  if (static_cast<int64_t>(points.size()) != point_count()) {
    throw InputError("landmarks: new set has " + std::to_string(points.size()) + " points; expected " +
                     std::to_string(point_count()));
  }
  sets.push_back(std::move(points));
}

LandmarkSet LandmarkSet::single_set(int64_t s) const {
  LandmarkSet out;
  out.names = names;
  out.unit = unit;
  out.sets.push_back(set(s));
  return out;
}

std::string LandmarkSet::default_name(int64_t i) {
  std::string name(1, 'L');
  name += std::to_string(i + 1);
  return name;
}

std::vector<std::string> LandmarkSet::check_invariants() const {
  std::vector<std::string> problems;
  for (size_t k = 0; k < sets.size(); ++k) {
    if (sets[k].size() != names.size()) {
      problems.push_back("set " + std::to_string(k) + " has " + std::to_string(sets[k].size()) +
                         " points but there are " + std::to_string(names.size()) + " names");
    }
    for (size_t i = 0; i < sets[k].size(); ++i) {
      for (double c : sets[k][i]) {
        if (!std::isfinite(c)) {
          problems.push_back("set " + std::to_string(k) + " point " + std::to_string(i) +
                             " has a non-finite coordinate");
          break;
        }
      }
    }
  }
  return problems;
}

uint64_t LandmarkSet::bytes() const {
  uint64_t b = sizeof(LandmarkSet);
  for (const auto& n : names) b += n.capacity();
  for (const auto& s : sets) b += s.capacity() * sizeof(Vec3);
  return b;
}

std::string LandmarkSet::describe() const {
  std::ostringstream s;
  s << type_ids::landmarks << " " << set_count() << " set(s) of " << point_count() << " point(s)";
  return s.str();
}

}  // namespace skel
