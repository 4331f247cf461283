#include "skel/mesh.hpp"

#include <cmath>
#include <sstream>

namespace skel {

int64_t Mesh::add_line(const std::vector<int64_t>& ids) {
  if (ids.size() < 2) throw Error("mesh line with " + std::to_string(ids.size()) + " vertices (needs >= 2)");
  line_vertices.insert(line_vertices.end(), ids.begin(), ids.end());
  line_offsets.push_back(static_cast<int64_t>(line_vertices.size()));
  return line_count() - 1;
}

std::vector<std::string> Mesh::check_invariants() const {
  std::vector<std::string> out;
  const int64_t nv = vertex_count();
  for (int64_t v = 0; v < nv; ++v)
    if (!std::isfinite(points[v][0]) || !std::isfinite(points[v][1]) || !std::isfinite(points[v][2])) {
      out.push_back("vertex " + std::to_string(v) + " is not finite");
      break;
    }
  for (int64_t t = 0; t < triangle_count(); ++t)
    for (int64_t id : triangles[t])
      if (id < 0 || id >= nv) {
        out.push_back("triangle " + std::to_string(t) + " names vertex " + std::to_string(id) + " of " + std::to_string(nv));
        t = triangle_count();
        break;
      }
  if (line_offsets.empty() || line_offsets.front() != 0) {
    out.push_back("line offsets do not start at 0");
  } else {
    for (int64_t l = 0; l < line_count(); ++l)
      if (line_offsets[l + 1] - line_offsets[l] < 2) {
        out.push_back("line " + std::to_string(l) + " has fewer than 2 vertices");
        break;
      }
    if (line_offsets.back() != static_cast<int64_t>(line_vertices.size()))
      out.push_back("line offsets end at " + std::to_string(line_offsets.back()) + ", not at " +
                    std::to_string(line_vertices.size()) + " line vertices");
    for (int64_t id : line_vertices)
      if (id < 0 || id >= nv) {
        out.push_back("a line names vertex " + std::to_string(id) + " of " + std::to_string(nv));
        break;
      }
  }
  auto sizes = [&](const char* what, const MeshAttributes& m, int64_t n) {
    for (const auto& [name, a] : m)
      if (attribute_size(a) != n)
        out.push_back(std::string(what) + " attribute '" + name + "' has " + std::to_string(attribute_size(a)) +
                      " values for " + std::to_string(n) + " elements");
  };
  sizes("vertex", vertex_attributes, nv);
  sizes("triangle", triangle_attributes, triangle_count());
  sizes("line", line_attributes, line_count());
  return out;
}

uint64_t Mesh::bytes() const {
  uint64_t b = points.size() * sizeof(Point) + triangles.size() * sizeof(Triangle) +
               (line_offsets.size() + line_vertices.size()) * sizeof(int64_t);
  for (const auto* m : {&vertex_attributes, &triangle_attributes, &line_attributes})
    for (const auto& [n, a] : *m) b += static_cast<uint64_t>(attribute_size(a)) * 4;
  return b;
}

std::string Mesh::describe() const {
  std::ostringstream s;
  s << "mesh " << vertex_count() << " vertices, " << triangle_count() << " triangles, " << line_count()
    << " lines (" << unit << ")";
  auto list = [&](const char* what, const MeshAttributes& m) {
    if (m.empty()) return;
    s << ", " << what << ":";
    for (const auto& [n, a] : m) s << " " << n;
  };
  list("vertex attributes", vertex_attributes);
  list("triangle attributes", triangle_attributes);
  list("line attributes", line_attributes);
  return s.str();
}

bool operator==(const Mesh& a, const Mesh& b) {
  return a.points == b.points && a.triangles == b.triangles && a.line_offsets == b.line_offsets &&
         a.line_vertices == b.line_vertices && a.vertex_attributes == b.vertex_attributes &&
         a.triangle_attributes == b.triangle_attributes && a.line_attributes == b.line_attributes &&
         a.unit == b.unit && a.frame_origin == b.frame_origin && a.frame_direction == b.frame_direction;
}

}  // namespace skel
