#include "final_outputs.hpp"

#include <map>
#include <set>
#include <string>
#include <vector>

namespace skel::gui {

namespace {

enum class Kind { Mesh, Graph, Volume, Other };

Kind kind_of(const DataPtr& d) {
  if (!d) return Kind::Other;
  const std::string t = d->type_id();
  if (t == type_ids::mesh) return Kind::Mesh;
  if (t == type_ids::graph) return Kind::Graph;
  if (t.rfind("volume.", 0) == 0) return Kind::Volume;
  return Kind::Other;
}

}  // namespace

QStringList final_geometry_outputs(const Pipeline& pipeline, const Registry& registry,
                                   const std::function<DataPtr(const std::string&, const std::string&)>& output) {
  std::vector<std::string> order;
  try {
    order = pipeline.topological_order();
  } catch (const std::exception&) {
    return {};  // a cycle: nothing ran
  }
  // Direct consumers of each node.
  std::map<std::string, std::set<std::string>> users;
  for (const auto& n : pipeline.nodes())
    for (const auto& [port, ref] : n.inputs) users[ref.node].insert(n.id);
  // The kinds of computed outputs of each node.
  std::map<std::string, std::set<Kind>> kinds;
  struct Candidate {
    std::string node, port;
    Kind kind;
  };
  std::vector<Candidate> candidates;  // in topological order
  for (const auto& id : order) {
    const PipelineNode* n = pipeline.find(id);
    const ModuleSpec* spec = n ? registry.find(n->module) : nullptr;
    if (!spec) continue;
    for (const auto& o : spec->outputs()) {
      const Kind k = kind_of(output(id, o.name));
      if (k == Kind::Other) continue;
      kinds[id].insert(k);
      candidates.push_back({id, o.name, k});
    }
  }
  // True when a node downstream of `id` computed an output of kind `k`.
  auto derived_downstream = [&](const std::string& id, Kind k) {
    std::set<std::string> seen;
    std::vector<std::string> stack(users[id].begin(), users[id].end());
    while (!stack.empty()) {
      const std::string u = stack.back();
      stack.pop_back();
      if (!seen.insert(u).second) continue;
      if (kinds[u].count(k)) return true;
      for (const auto& v : users[u]) stack.push_back(v);
    }
    return false;
  };
  auto last_sink = [&](Kind k) -> QString {
    QString best;
    for (const auto& c : candidates)
      if (c.kind == k && !derived_downstream(c.node, k)) best = QString::fromStdString(c.node + "." + c.port);
    return best;
  };
  QStringList out;
  for (Kind k : {Kind::Mesh, Kind::Graph})
    if (QString s = last_sink(k); !s.isEmpty()) out << s;
  if (out.isEmpty())
    if (QString s = last_sink(Kind::Volume); !s.isEmpty()) out << s;
  return out;
}

}  // namespace skel::gui
