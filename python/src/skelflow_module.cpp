// _skelflow: the compiled half of `import skelflow` (the package's Python half is python/skelflow/).
//
// What it gives Python:
//   - specs(): every registered module's spec (ports, parameters with types, defaults, ranges, docs),
//     from which skelflow.modules generates one function per module at import time;
//   - Data: a handle on one framework data object (shared, never copied), and conversions between
//     data objects and NumPy: volumes both ways without copies, graphs and tables as arrays;
//   - Pipeline: the framework's pipeline model (the YAML the GUI and the CLI read and write);
//   - run(): a pipeline run through the framework's Executor, as `skelflow run` does, with data
//     given from Python replacing nodes' outputs; run_module(): one module as a one-node pipeline
//     through the same executor, so its validation messages are the CLI's.
// The GIL is released while modules run; Ctrl+C cancels the run through the executor's cancel flag.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <exception>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "skel/error.hpp"
#include "skel/executor.hpp"
#include "skel/module.hpp"
#include "skel/pipeline.hpp"
#include "skel/plugin.hpp"
#include "skel/spatial_graph.hpp"
#include "skel/table.hpp"
#include "skel/volume.hpp"

namespace py = pybind11;
using namespace skel;

namespace {

// ---------------------------------------------------------------- data handles
// One data object, shared with the framework (published data objects are immutable).
struct Data {
  DataPtr ptr;
  [[nodiscard]] std::string type_id() const { return ptr->type_id(); }
};

Data checked(const Data& d) {
  if (!d.ptr) throw Error("empty data handle");
  return d;
}

// ---------------------------------------------------------------- parameter values
ParamValue to_param(const py::handle& v, const std::string& what) {
  if (py::isinstance<py::bool_>(v)) return v.cast<bool>();
  if (py::isinstance<py::int_>(v)) return v.cast<int64_t>();
  if (py::isinstance<py::float_>(v)) return v.cast<double>();
  if (py::isinstance<py::str>(v)) return v.cast<std::string>();
  if (py::hasattr(v, "__fspath__")) return py::str(v.attr("__fspath__")()).cast<std::string>();
  // NumPy scalars
  if (py::hasattr(v, "dtype") && py::hasattr(v, "item") && py::len(v.attr("shape")) == 0)
    return to_param(v.attr("item")(), what);
  if ((py::isinstance<py::sequence>(v) && !py::isinstance<py::bytes>(v)) || py::isinstance<py::array>(v)) {
    std::vector<py::object> items;
    for (const auto& x : py::reinterpret_borrow<py::iterable>(v)) {
      py::object item = py::reinterpret_borrow<py::object>(x);
      if (py::hasattr(item, "dtype") && py::hasattr(item, "item")) item = item.attr("item")();  // NumPy scalar
      if (py::isinstance<py::bool_>(item) || !(py::isinstance<py::int_>(item) || py::isinstance<py::float_>(item)))
        throw InputError(what + ": expected a list of numbers");
      items.push_back(std::move(item));
    }
    const bool all_int =
        std::all_of(items.begin(), items.end(), [](const py::object& x) { return py::isinstance<py::int_>(x); });
    if (all_int) {
      std::vector<int64_t> r;
      for (const auto& x : items) r.push_back(x.cast<int64_t>());
      return r;
    }
    std::vector<double> r;
    for (const auto& x : items) r.push_back(x.cast<double>());
    return r;
  }
  throw InputError(what + ": cannot use a value of Python type " +
                   py::str(py::type::handle_of(v).attr("__name__")).cast<std::string>());
}

py::object from_param(const ParamValue& v) {
  return std::visit([](const auto& x) -> py::object { return py::cast(x); }, v);
}

// ---------------------------------------------------------------- module specs
py::dict port_dict(const PortSpec& p) {
  py::dict d;
  d["name"] = p.name;
  d["types"] = p.types;
  d["doc"] = p.doc;
  d["required"] = p.required;
  return d;
}

const char* role_name(PathRole r) {
  switch (r) {
    case PathRole::Input: return "input";
    case PathRole::Output: return "output";
    case PathRole::None: break;
  }
  return "";
}

py::list specs() {
  py::list out;
  for (const ModuleSpec* m : Registry::instance().specs()) {
    py::dict d;
    d["name"] = m->name();
    d["family"] = m->family();
    d["doc"] = m->doc();
    d["details"] = m->details();
    py::list ins, outs, params;
    for (const auto& p : m->inputs()) ins.append(port_dict(p));
    for (const auto& p : m->outputs()) outs.append(port_dict(p));
    for (const auto& p : m->params()) {
      py::dict q;
      q["name"] = p.name;
      q["type"] = to_string(p.type);
      q["default"] = from_param(p.default_value);
      q["doc"] = p.doc;
      q["unit"] = p.unit;
      q["min"] = p.min ? py::cast(*p.min) : py::none();
      q["max"] = p.max ? py::cast(*p.max) : py::none();
      q["choices"] = p.choices;
      q["list_length"] = p.list_length;
      q["optional"] = p.optional_value;
      q["path_role"] = role_name(p.path_role);
      q["extensions"] = p.extensions;
      q["old_names"] = p.old_names;
      params.append(q);
    }
    d["inputs"] = ins;
    d["outputs"] = outs;
    d["params"] = params;
    out.append(d);
  }
  return out;
}

// ---------------------------------------------------------------- volumes <-> NumPy
// Keeps a Python object alive from C++ (a data object may be freed on a worker thread, so the
// reference is dropped with the GIL held).
std::shared_ptr<const void> keep_alive(py::object o) {
  auto* held = new py::object(std::move(o));
  return std::shared_ptr<const void>(held, [](const py::object* p) {
    py::gil_scoped_acquire gil;
    delete p;
  });
}

Grid grid_of(const py::array& a, const std::array<double, 3>& spacing_zyx, const std::array<double, 3>& origin_zyx,
             const std::string& unit) {
  return Grid(Dims{a.shape(2), a.shape(1), a.shape(0)}, Vec3{spacing_zyx[2], spacing_zyx[1], spacing_zyx[0]},
              Vec3{origin_zyx[2], origin_zyx[1], origin_zyx[0]}, unit.empty() ? std::string(kDefaultUnit) : unit);
}

template <class T>
Data wrap_typed(const py::array& a, const Grid& g) {
  // The volume reads the array's memory in place and holds a reference to the array.
  T* data = static_cast<T*>(const_cast<void*>(a.data()));
  return Data{std::make_shared<Volume<T>>(Volume<T>::wrap(g, data, keep_alive(a)))};
}

// A NumPy array [z][y][x] as a volume without a copy: C-contiguous, one of the voxel types.
Data volume_from_array(const py::array& a, std::array<double, 3> spacing, std::array<double, 3> origin,
                       const std::string& unit) {
  if (a.ndim() != 3)
    throw InputError("a volume is a 3-dimensional array [z][y][x]; this array has " + std::to_string(a.ndim()) +
                     " dimension(s)");
  if (!(a.flags() & py::array::c_style))
    throw InputError("the array is not C-contiguous (wrap it with numpy.ascontiguousarray)");
  const Grid g = grid_of(a, spacing, origin, unit);
  const py::dtype dt = a.dtype();
  const char kind = dt.kind();
  const auto size = dt.itemsize();
  if (dt.byteorder() != '>') {  // native (little-endian) byte order
    if (kind == 'u' && size == 1) return wrap_typed<uint8_t>(a, g);
    if (kind == 'u' && size == 2) return wrap_typed<uint16_t>(a, g);
    if (kind == 'u' && size == 4) return wrap_typed<uint32_t>(a, g);
    if (kind == 'u' && size == 8) return wrap_typed<uint64_t>(a, g);
    if (kind == 'i' && size == 4) return wrap_typed<int32_t>(a, g);
    if (kind == 'f' && size == 4) return wrap_typed<float>(a, g);
    if (kind == 'f' && size == 8) return wrap_typed<double>(a, g);
  }
  throw InputError("arrays of dtype " + py::str(static_cast<py::handle>(dt)).cast<std::string>() +
                   " are not volumes; use uint8, uint16, uint32, uint64, int32, float32 or float64 (or bool)");
}

// The voxels of a volume as a NumPy array [z][y][x] without a copy; the array holds a reference to
// the volume. Returns (array, spacing (z, y, x), origin (z, y, x), unit).
py::tuple volume_to_array(const Data& d) {
  checked(d);
  return visit_volume(*d.ptr, "volume_to_array", [&](const auto& v) -> py::tuple {
    using T = typename std::decay_t<decltype(v)>::value_type;
    auto* keep = new DataPtr(d.ptr);
    py::capsule owner(keep, [](void* p) { delete static_cast<DataPtr*>(p); });
    const auto nx = static_cast<py::ssize_t>(v.nx()), ny = static_cast<py::ssize_t>(v.ny()),
               nz = static_cast<py::ssize_t>(v.nz());
    const auto s = static_cast<py::ssize_t>(sizeof(T));
    py::array_t<T> arr({nz, ny, nx}, {nx * ny * s, nx * s, s}, const_cast<T*>(v.data()), owner);
    const auto& sp = v.spacing();
    const auto& o = v.origin();
    return py::make_tuple(arr, py::make_tuple(sp[2], sp[1], sp[0]), py::make_tuple(o[2], o[1], o[0]), v.unit());
  });
}

// ---------------------------------------------------------------- graphs
template <class T>
py::array_t<T> to_array(const std::vector<T>& v) {
  py::array_t<T> a(static_cast<py::ssize_t>(v.size()));
  std::copy(v.begin(), v.end(), a.mutable_data());
  return a;
}

py::array_t<double> points_array(const std::vector<Vec3>& pts) {
  py::array_t<double> a({static_cast<py::ssize_t>(pts.size()), py::ssize_t{3}});
  auto m = a.mutable_unchecked<2>();
  for (size_t i = 0; i < pts.size(); ++i)
    for (int k = 0; k < 3; ++k) m(static_cast<py::ssize_t>(i), k) = pts[i][static_cast<size_t>(k)];
  return a;
}

py::dict grid_dict(const Grid& g) {
  py::dict d;
  d["dims"] = py::make_tuple(g.dims[0], g.dims[1], g.dims[2]);
  d["spacing"] = py::make_tuple(g.spacing[0], g.spacing[1], g.spacing[2]);
  d["origin"] = py::make_tuple(g.origin[0], g.origin[1], g.origin[2]);
  return d;
}

const SpatialGraph& graph_of(const Data& d) {
  auto* g = dynamic_cast<const SpatialGraph*>(checked(d).ptr.get());
  if (!g) throw InputError("expected a graph, got " + d.ptr->type_id());
  return *g;
}

// The whole graph as arrays (copies): positions (N, 3) x/y/z, edges (E, 2), points (one (k, 3) array
// per edge), attributes by name, and the source grid (x, y, z order, as in the files).
py::dict graph_to_dict(const Data& d) {
  const SpatialGraph& g = graph_of(d);
  py::dict r;
  r["positions"] = points_array(g.positions);
  py::array_t<int64_t> edges({static_cast<py::ssize_t>(g.edges.size()), py::ssize_t{2}});
  auto e = edges.mutable_unchecked<2>();
  py::list points;
  for (size_t i = 0; i < g.edges.size(); ++i) {
    e(static_cast<py::ssize_t>(i), 0) = g.edges[i].node0;
    e(static_cast<py::ssize_t>(i), 1) = g.edges[i].node1;
    points.append(points_array(g.edges[i].points));
  }
  r["edges"] = edges;
  r["points"] = points;
  auto attrs = [](const auto& m) {
    py::dict a;
    for (const auto& [name, values] : m) a[py::str(name)] = to_array(values);
    return a;
  };
  r["node_attributes"] = attrs(g.node_attributes);
  r["node_labels"] = attrs(g.node_labels);
  r["edge_attributes"] = attrs(g.edge_attributes);
  r["edge_labels"] = attrs(g.edge_labels);
  py::dict pa;
  for (const auto& [name, per_edge] : g.point_attributes) {
    py::list l;
    for (const auto& values : per_edge) l.append(to_array(values));
    pa[py::str(name)] = l;
  }
  r["point_attributes"] = pa;
  r["source_grid"] = grid_dict(g.source_grid);
  return r;
}

Vec3 vec3(const py::handle& h, const std::string& what) {
  auto v = py::cast<std::vector<double>>(h);
  if (v.size() != 3) throw InputError(what + ": expected 3 coordinates, got " + std::to_string(v.size()));
  return {v[0], v[1], v[2]};
}

std::vector<Vec3> points_from(const py::handle& h, const std::string& what) {
  py::array_t<double, py::array::c_style | py::array::forcecast> a(py::reinterpret_borrow<py::object>(h));
  if (a.ndim() != 2 || a.shape(1) != 3) throw InputError(what + ": expected an array of shape (n, 3)");
  std::vector<Vec3> pts(static_cast<size_t>(a.shape(0)));
  auto u = a.unchecked<2>();
  for (py::ssize_t i = 0; i < a.shape(0); ++i) pts[static_cast<size_t>(i)] = {u(i, 0), u(i, 1), u(i, 2)};
  return pts;
}

// The inverse of graph_to_dict; checks the graph's invariants (end points equal node positions,
// attribute sizes) and raises naming what is off.
Data graph_from_dict(const py::dict& d) {
  auto g = std::make_shared<SpatialGraph>();
  g->positions = points_from(d["positions"], "positions");
  py::array_t<int64_t, py::array::c_style | py::array::forcecast> edges(d["edges"]);
  if (edges.size() > 0 && (edges.ndim() != 2 || edges.shape(1) != 2))
    throw InputError("edges: expected an array of shape (m, 2)");
  py::list points = d.contains("points") ? py::list(d["points"]) : py::list();
  const py::ssize_t m = edges.size() == 0 ? 0 : edges.shape(0);
  if (points.size() != 0 && static_cast<py::ssize_t>(points.size()) != m)
    throw InputError("points: expected one polyline per edge (" + std::to_string(m) + "), got " +
                     std::to_string(points.size()));
  for (py::ssize_t i = 0; i < m; ++i) {
    const int64_t a = edges.at(i, 0), b = edges.at(i, 1);
    std::vector<Vec3> pts;
    if (points.size() != 0 && !points[static_cast<size_t>(i)].is_none())
      pts = points_from(points[static_cast<size_t>(i)], "points of edge " + std::to_string(i));
    if (a < 0 || b < 0 || a >= g->node_count() || b >= g->node_count())
      throw InputError("edge " + std::to_string(i) + ": node ids " + std::to_string(a) + ", " + std::to_string(b) +
                       " out of range (" + std::to_string(g->node_count()) + " nodes)");
    g->add_edge(a, b, std::move(pts));
  }
  auto fill = [&](const char* key, auto& target) {
    if (!d.contains(key)) return;
    using V = typename std::decay_t<decltype(target)>::mapped_type::value_type;
    for (const auto& [name, values] : py::dict(d[key]))
      target[py::cast<std::string>(name)] = py::cast<std::vector<V>>(values);
  };
  fill("node_attributes", g->node_attributes);
  fill("node_labels", g->node_labels);
  fill("edge_attributes", g->edge_attributes);
  fill("edge_labels", g->edge_labels);
  if (d.contains("point_attributes"))
    for (const auto& [name, per_edge] : py::dict(d["point_attributes"]))
      g->point_attributes[name.cast<std::string>()] = py::cast<std::vector<std::vector<float>>>(per_edge);
  if (d.contains("source_grid") && !d["source_grid"].is_none()) {
    py::dict sg(d["source_grid"]);
    auto dims = py::cast<std::vector<int64_t>>(sg["dims"]);
    if (dims.size() != 3) throw InputError("source_grid: expected 3 dims");
    g->source_grid = Grid(Dims{dims[0], dims[1], dims[2]}, vec3(sg["spacing"], "source_grid spacing"),
                          vec3(sg["origin"], "source_grid origin"));
  }
  const auto problems = g->check_invariants();
  if (!problems.empty()) {
    std::string msg = "not a valid graph:";
    for (const auto& p : problems) msg += "\n  " + p;
    throw InputError(msg);
  }
  return Data{std::move(g)};
}

// ---------------------------------------------------------------- tables
// [(name, unit, values)], values a NumPy array (int64, float64) or a list of str.
py::list table_to_list(const Data& d) {
  auto* t = dynamic_cast<const Table*>(checked(d).ptr.get());
  if (!t) throw InputError("expected a table, got " + d.ptr->type_id());
  py::list r;
  for (const auto& c : t->columns()) {
    py::object values = std::visit(
        [](const auto& v) -> py::object {
          using E = typename std::decay_t<decltype(v)>::value_type;
          if constexpr (std::is_same_v<E, std::string>) return py::cast(v);
          else return to_array(v);
        },
        c.values);
    r.append(py::make_tuple(c.name, c.unit, values));
  }
  return r;
}

Data table_from_list(const py::list& columns) {
  auto t = std::make_shared<Table>();
  for (const auto& item : columns) {
    auto tup = py::cast<py::tuple>(item);
    const auto name = tup[0].cast<std::string>();
    const auto unit = tup[1].cast<std::string>();
    py::array a = py::array::ensure(tup[2]);
    if (a && a.dtype().kind() == 'i') t->add(name, py::cast<std::vector<int64_t>>(tup[2]), unit);
    else if (a && a.dtype().kind() == 'u') t->add(name, py::cast<std::vector<int64_t>>(tup[2]), unit);
    else if (a && (a.dtype().kind() == 'f' || a.dtype().kind() == 'b'))
      t->add(name, py::cast<std::vector<double>>(tup[2]), unit);
    else t->add(name, py::cast<std::vector<std::string>>(tup[2]), unit);
  }
  return Data{std::move(t)};
}

// ---------------------------------------------------------------- running
// A node whose outputs are data given from Python: it replaces a node of the pipeline (e.g. a
// reader) for one run, so the rest of the pipeline runs unchanged.
class GivenOutputs final : public Module {
public:
  explicit GivenOutputs(std::map<std::string, DataPtr> data) : data_(std::move(data)) {}
  void run(RunContext& ctx) override {
    for (const auto& [port, d] : data_) ctx.output(port, d);
  }

private:
  std::map<std::string, DataPtr> data_;
};

std::vector<std::string> node_ids(const Pipeline& p) {
  std::vector<std::string> ids;
  for (const auto& n : p.nodes()) ids.push_back(n.id);
  return ids;
}

// Replaces the nodes named in `given` ("node.port" -> data) by GivenOutputs nodes registered in
// `reg` (a copy of the global registry). The node keeps its id and its users' connections.
void substitute_given(Pipeline& p, const std::map<std::string, DataPtr>& given, Registry& reg) {
  std::map<std::string, std::map<std::string, DataPtr>> by_node;
  for (const auto& [key, data] : given) {
    auto ref = parse_port_ref(key);
    if (!ref) throw InputError("inputs: '" + key + "': expected node.port");
    const PipelineNode* n = p.find(ref->node);
    if (!n) throw InputError("inputs: '" + key + "': no node '" + ref->node + "' in " + p.file() +
                             did_you_mean(ref->node, node_ids(p)));
    const ModuleSpec* spec = reg.find(n->module);
    if (spec && !spec->find_output(ref->port)) {
      std::vector<std::string> names;
      std::string list;
      for (const auto& o : spec->outputs()) {
        names.push_back(o.name);
        list += (list.empty() ? "" : ", ") + o.name;
      }
      throw InputError("inputs: '" + key + "': node '" + ref->node + "' (" + n->module + ") has no output '" +
                       ref->port + "'" + did_you_mean(ref->port, names) + "; its outputs: " + list);
    }
    if (!data) throw InputError("inputs: '" + key + "': no data");
    by_node[ref->node][ref->port] = data;
  }
  for (auto& [node, ports] : by_node) {
    PipelineNode* n = p.find(node);
    // Every output of the replaced node that another node reads must be given.
    for (const auto& other : p.nodes())
      for (const auto& [in_port, ref] : other.inputs)
        if (ref.node == node && !ports.count(ref.port))
          throw InputError("inputs: node '" + node + "' is replaced by given data, but node '" + other.id +
                           "' reads its output '" + ref.port + "', which was not given ('" + node + "." +
                           ref.port + "')");
    ModuleSpec spec("python.input." + node, "data given from Python for node '" + node + "'");
    for (const auto& [port, d] : ports) spec.add_output(port, {d->type_id()}, "given from Python");
    reg.add(spec, [data = ports] { return std::make_unique<GivenOutputs>(data); });
    n->module = spec.name();
    n->params.clear();
    n->param_pos.clear();
    n->param_origin.clear();
    n->inputs.clear();
    n->input_pos.clear();
  }
}

// Runs `f` on a worker thread with the GIL released; the calling (main) thread wakes every 50 ms,
// takes the GIL briefly and lets Python handle pending signals: Ctrl+C raises KeyboardInterrupt
// there, which sets `cancel` (the run stops at the modules' next interrupter check) and is raised
// once the run has ended.
template <class R>
R run_interruptible(std::atomic<bool>& cancel, std::function<R()> f) {
  std::packaged_task<R()> task(std::move(f));
  std::future<R> result = task.get_future();
  std::unique_ptr<py::error_already_set> interrupt;
  {
    py::gil_scoped_release release;
    std::thread worker(std::move(task));
    while (result.wait_for(std::chrono::milliseconds(50)) != std::future_status::ready) {
      if (interrupt) continue;
      py::gil_scoped_acquire gil;
      if (PyErr_CheckSignals() != 0) {
        interrupt = std::make_unique<py::error_already_set>();
        cancel.store(true);
      }
    }
    worker.join();
  }
  if (interrupt) {
    try {
      (void)result.get();
    } catch (...) {
      // The run ended because of the interrupt (Cancelled) or failed meanwhile: the interrupt wins.
    }
    throw std::move(*interrupt);
  }
  return result.get();
}

// The run report (as `skelflow run --report` writes it) of the last run or module call, for
// skelflow.last_report().
std::mutex g_report_mutex;
std::string g_last_report;

void remember_report(const Executor& ex) {
  const std::string json = ex.last_report().to_json();
  std::lock_guard lock(g_report_mutex);
  g_last_report = json;
}

struct RunArgs {
  std::map<std::string, ParamMap> overrides;
  std::map<std::string, DataPtr> given;
  int threads = 0;
  std::filesystem::path output_dir;
  bool allow_outside_output_dir = false;
  std::vector<std::string> targets;
  std::optional<std::vector<std::string>> outputs;  // "node.port" to return; all when not given
};

// Runs `pipeline` through the Executor as `skelflow run` does and returns the requested outputs.
std::map<std::string, DataPtr> run_pipeline(Pipeline p, RunArgs a) {
  Registry reg = Registry::instance();
  substitute_given(p, a.given, reg);
  std::atomic<bool> cancel{false};
  ExecOptions opt;
  opt.threads = a.threads;
  opt.output_dir = a.output_dir;
  opt.allow_outside_output_dir = a.allow_outside_output_dir;
  opt.targets = a.targets;
  opt.overrides = a.overrides;
  opt.keep_outputs = true;
  opt.cancel = &cancel;
  std::function<std::map<std::string, DataPtr>()> work = [&]() {
    Executor ex(reg);
    const ExecutionPlan plan = ex.plan(p, opt);  // validates (the same messages as the CLI)
    if (a.outputs)
      for (const auto& key : *a.outputs) {
        auto ref = parse_port_ref(key);
        const PipelineNode* n = ref ? plan.pipeline.find(ref->node) : nullptr;
        const ModuleSpec* spec = n ? reg.find(n->module) : nullptr;
        if (!spec || !spec->find_output(ref->port))
          throw InputError("outputs: '" + key + "' is not an output of a node of " + p.file());
        if (plan.index_of(ref->node) < 0)
          throw InputError("outputs: '" + key + "': node '" + ref->node + "' does not run for the targets given");
      }
    try {
      ex.run(p, opt);
    } catch (...) {
      remember_report(ex);
      throw;
    }
    remember_report(ex);
    std::map<std::string, DataPtr> out;
    for (const auto& pn : plan.nodes) {
      const ModuleSpec& spec = *reg.find(pn.module);
      for (const auto& port : spec.outputs()) {
        const std::string key = pn.id + "." + port.name;
        if (a.outputs && std::find(a.outputs->begin(), a.outputs->end(), key) == a.outputs->end()) continue;
        if (DataPtr d = ex.output(plan.pipeline, pn.id, port.name)) out[key] = std::move(d);
      }
    }
    return out;
  };
  return run_interruptible(cancel, std::move(work));
}

std::map<std::string, ParamMap> overrides_from(const py::dict& set) {
  std::map<std::string, ParamMap> r;
  for (const auto& [k, v] : set) {
    const auto key = k.cast<std::string>();
    const auto dot = key.find('.');
    if (dot == std::string::npos || dot == 0 || dot + 1 == key.size())
      throw InputError("set: '" + key + "': expected node.param");
    r[key.substr(0, dot)][key.substr(dot + 1)] = to_param(v, "set: '" + key + "'");
  }
  return r;
}

std::map<std::string, DataPtr> data_map(const py::dict& d) {
  std::map<std::string, DataPtr> r;
  for (const auto& [k, v] : d) r[k.cast<std::string>()] = checked(v.cast<Data>()).ptr;
  return r;
}

std::map<std::string, Data> wrap_outputs(const std::map<std::string, DataPtr>& m) {
  std::map<std::string, Data> r;
  for (const auto& [k, v] : m) r[k] = Data{v};
  return r;
}

// `message` without the "FILE: " that starts its lines: the one-node pipeline of a module function
// has no file, so its messages read as the CLI's for such a node without the position.
std::string without_file(const std::string& message, const std::string& file) {
  const std::string prefix = file + ": ";
  std::string out;
  size_t start = 0;
  while (start <= message.size()) {
    size_t end = message.find('\n', start);
    if (end == std::string::npos) end = message.size();
    std::string line = message.substr(start, end - start);
    if (line.starts_with(prefix)) line.erase(0, prefix.size());
    out += line;
    if (end == message.size()) break;
    out += '\n';
    start = end + 1;
  }
  return out;
}

// One module as a one-node pipeline (its inputs given as data): the same validation, execution,
// transactional files and messages as a node of a pipeline run by the CLI.
std::map<std::string, Data> run_module(const std::string& module, const py::dict& inputs, const py::dict& params,
                                       int threads, const std::filesystem::path& output_dir) {
  const ModuleSpec* spec = Registry::instance().find(module);
  if (!spec) {
    std::vector<std::string> names;
    for (const auto* s : Registry::instance().specs()) names.push_back(s->name());
    throw InputError("unknown module '" + module + "'" + did_you_mean(module, names));
  }
  Pipeline p;
  const std::string id = spec->name().substr(spec->name().find('.') + 1);
  p.add_node(id, module);
  for (const auto& [k, v] : params) {
    const auto name = k.cast<std::string>();
    p.set_param(id, name, to_param(v, "node '" + id + "' (" + module + "): parameter '" + name + "'"));
  }
  // Each given input comes from a node of its own whose module outputs that data on port "data".
  Registry reg = Registry::instance();
  for (const auto& [k, v] : inputs) {
    const auto port = k.cast<std::string>();
    if (v.is_none()) continue;
    DataPtr d = checked(v.cast<Data>()).ptr;
    const std::string src = p.unique_id("input_" + port);
    ModuleSpec s("python.input." + src, "data given from Python for input '" + port + "'");
    s.add_output("data", {d->type_id()}, "given from Python");
    reg.add(s, [data = std::map<std::string, DataPtr>{{"data", d}}] { return std::make_unique<GivenOutputs>(data); });
    p.add_node(src, s.name());
    p.find(id)->inputs[port] = PortRef{src, "data"};
  }
  std::atomic<bool> cancel{false};
  ExecOptions opt;
  opt.threads = threads;
  opt.output_dir = output_dir;
  opt.keep_outputs = true;
  opt.cancel = &cancel;
  opt.targets = {id};
  std::function<std::map<std::string, DataPtr>()> work = [&]() {
    Executor ex(reg);
    try {
      ex.run(p, opt);
    } catch (...) {
      remember_report(ex);
      throw;
    }
    remember_report(ex);
    std::map<std::string, DataPtr> out;
    for (const auto& port : spec->outputs())
      if (DataPtr d = ex.output(p, id, port.name)) out[port.name] = std::move(d);
    return out;
  };
  try {
    return wrap_outputs(run_interruptible(cancel, std::move(work)));
  } catch (const Cancelled&) {
    throw;
  } catch (const InputError& e) {
    throw InputError(without_file(e.what(), p.file()));
  } catch (const Error& e) {
    throw Error(without_file(e.what(), p.file()));
  }
}

}  // namespace

PYBIND11_MODULE(_skelflow, m) {
  m.doc() = "Skelflow's compiled core; use the `skelflow` package.";

  static py::exception<Error> error(m, "Error");
  static py::exception<InputError> input_error(m, "InputError", error.ptr());
  static py::exception<Cancelled> cancelled(m, "Cancelled", error.ptr());
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const Cancelled& e) {
      cancelled(e.what());
    } catch (const InputError& e) {
      input_error(e.what());
    } catch (const Error& e) {
      error(e.what());
    }
  });

  m.def("last_report", [] {
    std::lock_guard lock(g_report_mutex);
    return g_last_report;
  }, "The JSON run report of the last run or module call (empty before the first).");
  m.def("specs", &specs, "Every registered module's spec as a list of dicts.");
  m.def("version", [] { return std::string(SKEL_VERSION_STRING); });
  // Plugins (SKELFLOW_PLUGIN_PATH, the user folder) are loaded at import, before the package makes
  // a function of every module; a refused plugin is a Python warning naming the file and why.
  m.def("load_plugins", [] {
    const PluginLoadReport& r = load_plugins();
    py::list loaded;
    for (const auto& p : r.loaded) loaded.append(py::make_tuple(p.file, p.modules));
    return py::make_tuple(loaded, r.errors);
  }, "Loads the plugins once: ([(file, [module, ...]), ...], [error, ...]).");
  m.def("plugin_of_module", &plugin_of_module, "The plugin file a module came from, or '' when built in.");

  py::class_<Data>(m, "Data", "A Skelflow data object (volume, graph, table, landmarks, transform, ...).")
      .def_property_readonly("type_id", &Data::type_id)
      .def_property_readonly("bytes", [](const Data& d) { return checked(d).ptr->bytes(); })
      .def("describe", [](const Data& d) { return checked(d).ptr->describe(); })
      .def("__repr__", [](const Data& d) { return "<skelflow data " + checked(d).ptr->describe() + ">"; });

  m.def("volume_from_array", &volume_from_array, py::arg("array"), py::arg("spacing"), py::arg("origin"),
        py::arg("unit") = std::string(kDefaultUnit),
        "Wraps a C-contiguous 3-D array [z][y][x] as a volume without copying (the volume keeps the array "
        "alive). spacing and origin are in (z, y, x) order, in `unit`.");
  m.def("volume_to_array", &volume_to_array,
        "(array, spacing, origin, unit) of a volume: the array is the volume's memory (no copy) and keeps the "
        "volume alive; spacing and origin in (z, y, x) order.");
  m.def("wraps_array", [](const Data& d) {
    return visit_volume(*checked(d).ptr, "wraps_array", [](const auto& v) { return v.wraps_external_memory(); });
  });
  m.def("graph_to_dict", &graph_to_dict);
  m.def("graph_from_dict", &graph_from_dict);
  m.def("table_to_list", &table_to_list);
  m.def("table_from_list", &table_from_list);

  py::class_<Pipeline>(m, "Pipeline")
      .def(py::init<>())
      .def_static("load", &Pipeline::load_file, py::arg("path"))
      .def_static("parse", &Pipeline::parse, py::arg("text"), py::arg("file_name") = "<string>",
                  py::arg("base_dir") = std::filesystem::path("."))
      .def("to_yaml", &Pipeline::to_yaml)
      .def("save", &Pipeline::save, py::arg("path"))
      .def_property_readonly("file", &Pipeline::file)
      .def_property("base_dir", &Pipeline::base_dir, &Pipeline::set_base_dir)
      .def("node_ids", [](const Pipeline& p) { return node_ids(p); })
      .def("node_module", [](const Pipeline& p, const std::string& id) {
        const PipelineNode* n = p.find(id);
        if (!n) throw InputError("no node '" + id + "' in " + p.file() + did_you_mean(id, node_ids(p)));
        return n->module;
      })
      .def("node_params", [](const Pipeline& p, const std::string& id) {
        const PipelineNode* n = p.find(id);
        if (!n) throw InputError("no node '" + id + "' in " + p.file() + did_you_mean(id, node_ids(p)));
        py::dict d;
        for (const auto& [k, v] : n->params) d[py::str(k)] = from_param(v);
        return d;
      })
      .def("node_inputs", [](const Pipeline& p, const std::string& id) {
        const PipelineNode* n = p.find(id);
        if (!n) throw InputError("no node '" + id + "' in " + p.file() + did_you_mean(id, node_ids(p)));
        std::map<std::string, std::string> r;
        for (const auto& [port, ref] : n->inputs) r[port] = ref.str();
        return r;
      })
      .def("add_node", [](Pipeline& p, const std::string& id, const std::string& module) {
        if (!Registry::instance().find(module)) {
          std::vector<std::string> names;
          for (const auto* s : Registry::instance().specs()) names.push_back(s->name());
          throw InputError("node '" + id + "': unknown module '" + module + "'" + did_you_mean(module, names));
        }
        p.add_node(id, module);
      })
      .def("remove_node", &Pipeline::remove_node)
      .def("set_param", [](Pipeline& p, const std::string& node, const std::string& name, const py::object& v) {
        p.set_param(node, name, to_param(v, "node '" + node + "': parameter '" + name + "'"));
      })
      .def("reset_param", &Pipeline::reset_param)
      .def("connect", [](Pipeline& p, const std::string& from, const std::string& to) {
        auto a = parse_port_ref(from), b = parse_port_ref(to);
        if (!a) throw InputError("connect: '" + from + "': expected node.port");
        if (!b) throw InputError("connect: '" + to + "': expected node.port");
        const std::string why = p.connect(*a, b->node, b->port);
        if (!why.empty()) throw InputError("connect " + from + " -> " + to + ": " + why);
      })
      .def("validate", [](const Pipeline& p) {
        std::vector<std::string> r;
        for (const auto& d : validate(p)) r.push_back(d.format());
        return r;
      })
      .def("__eq__", [](const Pipeline& a, const Pipeline& b) { return a == b; });

  m.def(
      "run",
      [](const Pipeline& p, const py::dict& set, const py::dict& inputs, int threads,
         const std::filesystem::path& output_dir, bool allow_outside_output_dir,
         const std::vector<std::string>& targets, std::optional<std::vector<std::string>> outputs) {
        RunArgs a;
        a.overrides = overrides_from(set);
        a.given = data_map(inputs);
        a.threads = threads;
        a.output_dir = output_dir;
        a.allow_outside_output_dir = allow_outside_output_dir;
        a.targets = targets;
        a.outputs = std::move(outputs);
        return wrap_outputs(run_pipeline(p, std::move(a)));
      },
      py::arg("pipeline"), py::arg("set"), py::arg("inputs"), py::arg("threads"), py::arg("output_dir"),
      py::arg("allow_outside_output_dir"), py::arg("targets"), py::arg("outputs"));
  m.def("run_module", &run_module, py::arg("module"), py::arg("inputs"), py::arg("params"), py::arg("threads"),
        py::arg("output_dir"));
}
