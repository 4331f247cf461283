#include "pipeline_document.hpp"

#include <QFileInfo>
#include <QRegularExpression>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <set>
#include <utility>

#include "skel/error.hpp"

namespace skel::gui {

namespace {

// An edit as two complete states: cheap for pipelines (tens of nodes), exact to undo, and it keeps
// the engine's Pipeline the only graph model.
class StateCommand final : public QUndoCommand {
public:
  StateCommand(PipelineDocument* doc, const QString& text, DocState before, DocState after,
               PipelineDocument::Change change, QString node)
      : QUndoCommand(text), doc_(doc), before_(std::move(before)), after_(std::move(after)),
        change_(change), node_(std::move(node)) {}
  void undo() override { doc_->apply_state(before_, change_, node_); }
  void redo() override { doc_->apply_state(after_, change_, node_); }

private:
  PipelineDocument* doc_;
  DocState before_, after_;
  PipelineDocument::Change change_;
  QString node_;
};

std::string str(const QString& s) { return s.toStdString(); }
QString qstr(const std::string& s) { return QString::fromStdString(s); }

// Positions stored under gui: {positions: {id: [x, y]}}.
QMap<QString, QPointF> parse_positions(const std::string& gui_yaml) {
  QMap<QString, QPointF> out;
  if (gui_yaml.empty()) return out;
  try {
    YAML::Node gui = YAML::Load(gui_yaml);
    if (!gui.IsMap() || !gui["positions"] || !gui["positions"].IsMap()) return out;
    for (const auto& kv : gui["positions"]) {
      const YAML::Node& v = kv.second;
      if (v.IsSequence() && v.size() == 2) {
        out.insert(qstr(kv.first.as<std::string>()), QPointF(v[0].as<double>(), v[1].as<double>()));
      }
    }
  } catch (const YAML::Exception&) {
    // The gui section is advisory: a malformed one only loses the layout.
  }
  return out;
}

std::string positions_yaml(const std::string& old_gui, const QMap<QString, QPointF>& positions,
                           const std::vector<PipelineNode>& nodes) {
  YAML::Node gui;
  try {
    if (!old_gui.empty()) gui = YAML::Load(old_gui);
  } catch (const YAML::Exception&) {
    gui = YAML::Node();
  }
  if (!gui.IsMap()) gui = YAML::Node(YAML::NodeType::Map);
  YAML::Node pos(YAML::NodeType::Map);
  for (const auto& n : nodes) {
    auto it = positions.find(qstr(n.id));
    if (it == positions.end()) continue;
    YAML::Node xy(YAML::NodeType::Sequence);
    xy.push_back(std::round(it->x()));
    xy.push_back(std::round(it->y()));
    xy.SetStyle(YAML::EmitterStyle::Flow);
    pos[n.id] = xy;
  }
  gui["positions"] = pos;
  YAML::Emitter e;
  e << gui;
  return e.c_str();
}

// Stem for new node ids: "segmentation.threshold" -> "threshold".
std::string id_stem(const std::string& module) {
  auto dot = module.find('.');
  std::string stem = dot == std::string::npos ? module : module.substr(dot + 1);
  return stem.empty() ? std::string("node") : stem;
}

}  // namespace

QString port_type_label(const PortSpec& port) {
  if (port.types == all_volume_types()) return "volume";
  if (port.types == integer_volume_types()) return "volume.int";
  QStringList parts;
  for (const auto& t : port.types) parts << qstr(t);
  return parts.join('|');
}

PipelineDocument::PipelineDocument(QObject* parent, const Registry& registry)
    : QObject(parent), registry_(registry) {
  connect(&undo_, &QUndoStack::cleanChanged, this, [this](bool clean) { emit modified_changed(!clean); });
}

QStringList PipelineDocument::node_ids() const {
  QStringList ids;
  for (const auto& n : state_.pipeline.nodes()) ids << qstr(n.id);
  return ids;
}

bool PipelineDocument::has_node(const QString& id) const { return state_.pipeline.find(str(id)) != nullptr; }

const ModuleSpec* PipelineDocument::spec(const QString& node) const {
  const PipelineNode* n = state_.pipeline.find(str(node));
  return n ? registry_.find(n->module) : nullptr;
}

QPointF PipelineDocument::position(const QString& node) const { return state_.positions.value(node); }

void PipelineDocument::clear() {
  undo_.clear();
  state_ = DocState{};
  file_path_.clear();
  emit document_reset();
  emit file_path_changed(file_path_);
  emit modified_changed(false);
}

void PipelineDocument::load(const QString& path) {
  Pipeline p = Pipeline::load_file(str(path));
  undo_.clear();
  state_ = DocState{std::move(p), {}};
  set_positions_from_gui_section();
  file_path_ = QFileInfo(path).absoluteFilePath();
  emit document_reset();
  emit file_path_changed(file_path_);
  emit modified_changed(false);
}

void PipelineDocument::load_text(const QString& yaml, const QString& file_name, const QString& base_dir) {
  Pipeline p = Pipeline::parse(str(yaml), str(file_name), str(base_dir));
  undo_.clear();
  state_ = DocState{std::move(p), {}};
  set_positions_from_gui_section();
  file_path_.clear();
  emit document_reset();
  emit file_path_changed(file_path_);
  emit modified_changed(false);
}

void PipelineDocument::set_positions_from_gui_section() {
  state_.positions = parse_positions(state_.pipeline.gui_yaml());
  // Nodes without a stored position: columns by their depth in the graph, wrapped into bands of
  // layout_columns_ columns (see set_layout_columns).
  std::map<std::string, int> depth;
  std::vector<std::string> order;
  try {
    order = state_.pipeline.topological_order();
  } catch (const Error&) {
    for (const auto& n : state_.pipeline.nodes()) order.push_back(n.id);
  }
  std::map<int, std::vector<std::string>> column_nodes;  // per depth, in order
  for (const auto& id : order) {
    const PipelineNode* n = state_.pipeline.find(id);
    int d = 0;
    for (const auto& [port, ref] : n->inputs) {
      auto it = depth.find(ref.node);
      if (it != depth.end()) d = std::max(d, it->second + 1);
    }
    depth[id] = d;
    column_nodes[d].push_back(id);
  }
  auto height_of = [&](const std::string& id) {
    const PipelineNode* n = state_.pipeline.find(id);
    return node_height(n ? registry_.find(n->module) : nullptr) + kLayoutGap;
  };
  // Each band is as tall as its tallest column.
  const int columns = layout_columns_;
  const int band_count = column_nodes.empty() ? 0 : column_nodes.rbegin()->first / columns + 1;
  std::vector<double> band_top(static_cast<size_t>(band_count), 0.0);
  double top = 0;
  for (int b = 0; b < band_count; ++b) {
    band_top[static_cast<size_t>(b)] = top;
    double tallest = 0;
    for (int c = b * columns; c < (b + 1) * columns; ++c) {
      double h = 0;
      if (auto it = column_nodes.find(c); it != column_nodes.end())
        for (const auto& id : it->second) h += height_of(id);
      tallest = std::max(tallest, h);
    }
    top += tallest + kLayoutBandGap;
  }
  for (const auto& [d, ids] : column_nodes) {
    double y = band_top[static_cast<size_t>(d / columns)];
    for (const auto& id : ids) {
      const QString qid = qstr(id);
      if (!state_.positions.contains(qid)) state_.positions.insert(qid, QPointF((d % columns) * kLayoutColumnStep, y));
      y += height_of(id);
    }
  }
}

double PipelineDocument::node_height(const ModuleSpec* spec) {
  const size_t rows = spec ? std::max(spec->inputs().size(), spec->outputs().size()) : 0;
  return kNodeHeader + kNodeRow * static_cast<double>(rows) + kNodeFooter;
}

std::string PipelineDocument::gui_section() const {
  return positions_yaml(state_.pipeline.gui_yaml(), state_.positions, state_.pipeline.nodes());
}

QString PipelineDocument::to_yaml() const {
  Pipeline copy = state_.pipeline;
  copy.set_gui_yaml(gui_section());
  return qstr(copy.to_yaml());
}

void PipelineDocument::save(const QString& path) {
  state_.pipeline.set_gui_yaml(gui_section());
  state_.pipeline.save(str(path));
  file_path_ = QFileInfo(path).absoluteFilePath();
  undo_.setClean();
  emit file_path_changed(file_path_);
  emit modified_changed(false);
}

void PipelineDocument::apply_state(const DocState& state, Change change, const QString& node) {
  // Keep the folder relative paths resolve against: it belongs to the file, not to the edit.
  const std::filesystem::path base = state_.pipeline.base_dir();
  const std::string gui = state_.pipeline.gui_yaml();
  state_ = state;
  state_.pipeline.set_base_dir(base);
  state_.pipeline.set_gui_yaml(gui);
  switch (change) {
    case Change::Structure: emit graph_changed(); break;
    case Change::Param: emit param_changed(node); break;
    case Change::Move: emit nodes_moved(state_.positions.keys()); break;
  }
}

void PipelineDocument::push(const QString& text, DocState after, Change change, const QString& node) {
  undo_.push(new StateCommand(this, text, state_, std::move(after), change, node));
}

QString PipelineDocument::add_node(const QString& module, QPointF pos, QString* error) {
  if (!registry_.find(str(module))) {
    if (error) *error = "unknown module '" + module + "'";
    return {};
  }
  DocState after = state_;
  const std::string id = after.pipeline.unique_id(id_stem(str(module)));
  after.pipeline.add_node(id, str(module));
  after.positions.insert(qstr(id), pos);
  push("Add " + qstr(id), std::move(after), Change::Structure);
  return qstr(id);
}

void PipelineDocument::remove_nodes(const QStringList& ids) {
  DocState after = state_;
  int removed = 0;
  for (const QString& id : ids) {
    if (!after.pipeline.find(str(id))) continue;
    after.pipeline.remove_node(str(id));
    after.positions.remove(id);
    ++removed;
  }
  if (removed == 0) return;
  push(removed == 1 ? "Delete " + ids.front() : QString("Delete %1 nodes").arg(removed), std::move(after),
       Change::Structure);
}

void PipelineDocument::move_nodes(const QMap<QString, QPointF>& new_positions) {
  DocState after = state_;
  bool changed = false;
  for (auto it = new_positions.begin(); it != new_positions.end(); ++it) {
    if (!after.positions.contains(it.key()) || after.positions.value(it.key()) == it.value()) continue;
    after.positions[it.key()] = it.value();
    changed = true;
  }
  if (!changed) return;
  push(new_positions.size() == 1 ? "Move " + new_positions.firstKey() : QString("Move %1 nodes").arg(new_positions.size()),
       std::move(after), Change::Move);
}

QString PipelineDocument::connect_ports(const QString& from_node, const QString& from_port,
                                        const QString& to_node, const QString& to_port) {
  DocState after = state_;
  PipelineNode* target = after.pipeline.find(str(to_node));
  if (target) {
    auto it = target->inputs.find(str(to_port));
    if (it != target->inputs.end() && it->second == PortRef{str(from_node), str(from_port)}) {
      return {};  // already connected exactly so
    }
  }
  const std::string reason =
      after.pipeline.connect(PortRef{str(from_node), str(from_port)}, str(to_node), str(to_port), registry_);
  if (!reason.empty()) return qstr(reason);
  push("Connect " + from_node + "." + from_port + " -> " + to_node + "." + to_port, std::move(after),
       Change::Structure);
  return {};
}

void PipelineDocument::disconnect_port(const QString& to_node, const QString& to_port) {
  const PipelineNode* n = state_.pipeline.find(str(to_node));
  if (!n || !n->inputs.count(str(to_port))) return;
  DocState after = state_;
  after.pipeline.disconnect(str(to_node), str(to_port));
  push("Disconnect " + to_node + "." + to_port, std::move(after), Change::Structure);
}

QString PipelineDocument::set_param(const QString& node, const QString& param, const ParamValue& value) {
  const PipelineNode* n = state_.pipeline.find(str(node));
  if (!n) return "unknown node '" + node + "'";
  const ModuleSpec* ms = registry_.find(n->module);
  if (!ms) return "unknown module '" + qstr(n->module) + "'";
  const ParamSpec* ps = ms->find_param(str(param));
  if (!ps) return "unknown parameter '" + param + "' of " + qstr(n->module);
  std::optional<ParamValue> v = coerce_param(*ps, value);
  if (!v) {
    return "parameter '" + param + "': expected " + QString(to_string(ps->type)) + ", got " +
           qstr(format_value(value));
  }
  if (std::string e = ps->check(*v); !e.empty()) return "parameter '" + param + "': " + qstr(e);
  auto old = n->params.find(ps->name);
  if (old != n->params.end() && old->second == *v) return {};
  DocState after = state_;
  after.pipeline.set_param(str(node), ps->name, *v);
  push("Set " + node + "." + param + " = " + qstr(format_value(*v)), std::move(after), Change::Param, node);
  return {};
}

void PipelineDocument::reset_param(const QString& node, const QString& param) {
  const PipelineNode* n = state_.pipeline.find(str(node));
  if (!n || !n->params.count(str(param))) return;
  DocState after = state_;
  after.pipeline.reset_param(str(node), str(param));
  push("Reset " + node + "." + param, std::move(after), Change::Param, node);
}

QString PipelineDocument::rename_node(const QString& id, const QString& new_id) {
  if (id == new_id) return {};
  if (!has_node(id)) return "unknown node '" + id + "'";
  if (has_node(new_id)) return "a node named '" + new_id + "' exists";
  static const QRegularExpression valid("^[A-Za-z_][A-Za-z0-9_]*$");
  if (!valid.match(new_id).hasMatch()) {
    return "node ids are letters, digits and '_', starting with a letter or '_'";
  }
  DocState after = state_;
  after.pipeline.rename_node(str(id), str(new_id));
  after.positions.insert(new_id, after.positions.value(id));
  after.positions.remove(id);
  push("Rename " + id + " -> " + new_id, std::move(after), Change::Structure);
  return {};
}

QString PipelineDocument::copy_nodes(const QStringList& ids) const {
  Pipeline snippet;
  std::set<std::string> chosen;
  for (const QString& id : ids) chosen.insert(str(id));
  QMap<QString, QPointF> pos;
  QPointF origin;
  bool first = true;
  for (const auto& n : state_.pipeline.nodes()) {
    if (!chosen.count(n.id)) continue;
    PipelineNode& c = snippet.add_node(n.id, n.module);
    c.params = n.params;
    for (const auto& [port, ref] : n.inputs) {
      if (chosen.count(ref.node)) c.inputs[port] = ref;
    }
    const QPointF p = state_.positions.value(qstr(n.id));
    if (first || p.x() < origin.x()) origin.setX(p.x());
    if (first || p.y() < origin.y()) origin.setY(p.y());
    first = false;
    pos.insert(qstr(n.id), p);
  }
  if (first) return {};
  for (auto it = pos.begin(); it != pos.end(); ++it) it.value() -= origin;
  snippet.set_gui_yaml(positions_yaml({}, pos, snippet.nodes()));
  return qstr(snippet.to_yaml());
}

QStringList PipelineDocument::paste(const QString& text, QPointF offset, QString* error) {
  Pipeline snippet;
  try {
    snippet = Pipeline::parse(str(text), "<clipboard>");
  } catch (const Error& e) {
    if (error) *error = "clipboard does not hold pipeline nodes: " + qstr(e.what());
    return {};
  }
  if (snippet.nodes().empty()) {
    if (error) *error = "clipboard holds no nodes";
    return {};
  }
  const QMap<QString, QPointF> rel = parse_positions(snippet.gui_yaml());
  DocState after = state_;
  std::map<std::string, std::string> new_id;
  QStringList ids;
  for (const auto& n : snippet.nodes()) {
    const std::string id = after.pipeline.unique_id(n.id);
    new_id[n.id] = id;
    PipelineNode& c = after.pipeline.add_node(id, n.module);
    c.params = n.params;
    after.positions.insert(qstr(id), rel.value(qstr(n.id)) + offset);
    ids << qstr(id);
  }
  for (const auto& n : snippet.nodes()) {
    for (const auto& [port, ref] : n.inputs) {
      auto src = new_id.find(ref.node);
      if (src == new_id.end()) continue;
      // Connections inside the snippet were valid where they were copied from; connect() re-checks.
      after.pipeline.connect(PortRef{src->second, ref.port}, new_id[n.id], port, registry_);
    }
  }
  push(ids.size() == 1 ? "Paste " + ids.front() : QString("Paste %1 nodes").arg(ids.size()), std::move(after),
       Change::Structure);
  return ids;
}

}  // namespace skel::gui
