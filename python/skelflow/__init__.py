"""Skelflow from Python: pipelines, every module as a function, NumPy volumes and networkx graphs.

    import numpy as np, skelflow
    out = skelflow.run("pipelines/demo.yaml", set={"phantom.seed": 7}, threads=2)
    skeleton = skelflow.modules.thinning.doht(mask=mask, priority=distance)
    G = graph.to_networkx()

Volumes are NumPy arrays indexed [z][y][x] (`skelflow.Volume`, an ndarray subclass with `spacing`,
`origin` and `unit`); they cross into Skelflow and back without copies. Graphs are `skelflow.Graph`
(`to_networkx()`, `Graph.from_networkx(G)`), tables `skelflow.Table` (a dict of NumPy arrays,
`to_pandas()`). Errors are `skelflow.Error` (`skelflow.InputError` for what the user can fix,
with the CLI's message). See docs/python.md.
"""
from __future__ import annotations

import inspect
import keyword
import os
import sys
import types
from typing import Any, Dict, Iterable, Mapping, Optional

import numpy as np

from . import _skelflow as _core

__all__ = [
    "Error", "InputError", "Cancelled", "Volume", "Graph", "Table", "Data", "Outputs", "Pipeline", "run",
    "modules", "module_names", "plugins", "branch_table", "last_report", "__version__",
]

__version__ = _core.version()

Error = _core.Error
InputError = _core.InputError
Cancelled = _core.Cancelled
Data = _core.Data

#: The unit of spacing, origin and graph coordinates unless a file says otherwise.
DEFAULT_UNIT = "µm"


# ---------------------------------------------------------------- volumes
class Volume(np.ndarray):
    """A volume: a NumPy array indexed [z][y][x] with `spacing`, `origin` (both in (z, y, x) order,
    like scikit-image's `spacing`) and `unit`.

    Volumes returned by Skelflow are views of the framework's memory (no copy); the array keeps that
    memory alive. Any C-contiguous array of dtype uint8, uint16, uint32, uint64, int32, float32,
    float64 (or bool, read as uint8) is passed to Skelflow without a copy.
    """

    def __new__(cls, array, spacing=(1.0, 1.0, 1.0), origin=(0.0, 0.0, 0.0), unit=DEFAULT_UNIT):
        obj = np.asarray(array).view(cls)
        obj.spacing = tuple(float(s) for s in spacing)
        obj.origin = tuple(float(o) for o in origin)
        obj.unit = unit
        return obj

    def __array_finalize__(self, obj):
        self.spacing = getattr(obj, "spacing", (1.0, 1.0, 1.0))
        self.origin = getattr(obj, "origin", (0.0, 0.0, 0.0))
        self.unit = getattr(obj, "unit", DEFAULT_UNIT)

    def __reduce__(self):
        state = super().__reduce__()
        return state[0], state[1], (state[2], self.spacing, self.origin, self.unit)

    def __setstate__(self, state):
        base, self.spacing, self.origin, self.unit = state
        super().__setstate__(base)


def _volume_to_data(a: np.ndarray) -> Data:
    spacing = getattr(a, "spacing", (1.0, 1.0, 1.0))
    origin = getattr(a, "origin", (0.0, 0.0, 0.0))
    arr = np.asarray(a)  # the plain ndarray view (no copy)
    if arr.dtype == np.bool_:
        arr = arr.view(np.uint8)  # same memory: False/True are bytes 0/1
    if not arr.flags.c_contiguous:
        arr = np.ascontiguousarray(arr)  # the one case that copies (documented)
    return _core.volume_from_array(arr, tuple(spacing), tuple(origin), getattr(a, "unit", DEFAULT_UNIT))


def _data_to_volume(d: Data) -> Volume:
    arr, spacing, origin, unit = _core.volume_to_array(d)
    v = arr.view(Volume)
    v.spacing, v.origin, v.unit = spacing, origin, unit
    return v


# ---------------------------------------------------------------- tables
class Table(dict):
    """A table: column name -> NumPy array (int64, float64) or list of str, in column order;
    `units` maps column names to their physical unit ("" when none)."""

    def __init__(self, columns=(), units: Optional[Mapping[str, str]] = None):
        super().__init__(columns)
        self.units = {name: (units or {}).get(name, "") for name in self}

    @classmethod
    def _from_data(cls, d: Data) -> "Table":
        cols = _core.table_to_list(d)
        t = cls([(name, values) for name, _, values in cols])
        t.units = {name: unit for name, unit, _ in cols}
        return t

    def _to_data(self) -> Data:
        cols = []
        for name, values in self.items():
            if not isinstance(values, np.ndarray) and len(values) and isinstance(values[0], str):
                cols.append((name, self.units.get(name, ""), list(values)))
            else:
                cols.append((name, self.units.get(name, ""), np.asarray(values)))
        return _core.table_from_list(cols)

    @property
    def rows(self) -> int:
        return len(next(iter(self.values()))) if self else 0

    def to_pandas(self):
        """The table as a pandas DataFrame (needs pandas); units in `df.attrs["units"]`."""
        try:
            import pandas as pd
        except ImportError as e:  # pragma: no cover - depends on the machine
            raise ImportError("Table.to_pandas() needs pandas (pip install pandas or apt install python3-pandas)") from e
        df = pd.DataFrame({name: values for name, values in self.items()})
        df.attrs["units"] = dict(self.units)
        return df


# ---------------------------------------------------------------- graphs
class Graph:
    """A spatial graph: nodes with positions (x, y, z, physical units), edges with polylines that
    include both end node positions, and named attributes per node, edge and polyline point."""

    def __init__(self, data: Data):
        if not isinstance(data, Data) or data.type_id != "graph":
            raise TypeError("Graph wraps a Skelflow graph; build one with Graph.from_networkx or Graph.from_arrays")
        self._data = data
        self._arrays = None

    def _dict(self) -> dict:
        if self._arrays is None:
            self._arrays = _core.graph_to_dict(self._data)
        return self._arrays

    def __repr__(self):
        return f"<skelflow.Graph {self._data.describe()}>"

    def describe(self) -> str:
        return self._data.describe()

    @property
    def node_count(self) -> int:
        return len(self._dict()["positions"])

    @property
    def edge_count(self) -> int:
        return len(self._dict()["edges"])

    def arrays(self) -> dict:
        """Everything as arrays: positions (N, 3), edges (E, 2), points (one (k, 3) array per edge),
        node_attributes, node_labels, edge_attributes, edge_labels, point_attributes, source_grid."""
        return self._dict()

    @classmethod
    def from_arrays(cls, positions, edges, points=None, node_attributes=None, node_labels=None,
                    edge_attributes=None, edge_labels=None, point_attributes=None, source_grid=None) -> "Graph":
        d = {
            "positions": np.asarray(positions, dtype=np.float64).reshape(-1, 3),
            "edges": np.asarray(edges, dtype=np.int64).reshape(-1, 2),
            "points": list(points) if points is not None else [],
            "node_attributes": dict(node_attributes or {}),
            "node_labels": dict(node_labels or {}),
            "edge_attributes": dict(edge_attributes or {}),
            "edge_labels": dict(edge_labels or {}),
            "point_attributes": dict(point_attributes or {}),
            "source_grid": source_grid,
        }
        return cls(_core.graph_from_dict(d))

    def to_networkx(self):
        """A networkx.MultiGraph: node ids 0..N-1 with `pos` (x, y, z) and the node attributes and
        labels by name; one edge per graph edge (key = edge id) with `points` (k, 3), the edge
        attributes and labels by name, and each point attribute as `point_<name>` (one value per
        point, e.g. `point_radius`). G.graph holds `source_grid` and which names are int labels."""
        import networkx as nx

        d = self._dict()
        G = nx.MultiGraph()
        G.graph["source_grid"] = d["source_grid"]
        G.graph["node_labels"] = sorted(d["node_labels"])
        G.graph["edge_labels"] = sorted(d["edge_labels"])
        pos = d["positions"]
        nattr = {k: v for k, v in d["node_attributes"].items()}
        nlab = d["node_labels"]
        for n in range(len(pos)):
            attrs = {name: float(v[n]) for name, v in nattr.items()}
            attrs.update({name: int(v[n]) for name, v in nlab.items()})
            G.add_node(n, pos=pos[n].copy(), **attrs)
        eattr, elab, pattr = d["edge_attributes"], d["edge_labels"], d["point_attributes"]
        for e, (u, v) in enumerate(d["edges"]):
            attrs = {name: float(a[e]) for name, a in eattr.items()}
            attrs.update({name: int(a[e]) for name, a in elab.items()})
            attrs.update({"point_" + name: np.asarray(a[e]) for name, a in pattr.items()})
            G.add_edge(int(u), int(v), key=e, points=d["points"][e], **attrs)
        return G

    @classmethod
    def from_networkx(cls, G) -> "Graph":
        """A Graph from a networkx graph (Graph, MultiGraph, directed or not). Nodes need `pos`
        (x, y, z); edges may have `points` (k, 3) running from one end node to the other (a straight
        segment if absent). Numeric node/edge attributes become attributes (float) or labels (int,
        or names listed in G.graph["node_labels"] / ["edge_labels"]); `point_<name>` edge arrays
        become point attributes. An edge runs from the node its polyline starts at. Edges keyed by
        distinct ints (as to_networkx makes them) keep that order."""
        nodes = list(G.nodes)
        index = {n: i for i, n in enumerate(nodes)}
        positions = np.zeros((len(nodes), 3))
        for i, n in enumerate(nodes):
            data = G.nodes[n]
            if "pos" not in data:
                raise InputError(f"node {n!r} has no 'pos' (x, y, z)")
            positions[i] = np.asarray(data["pos"], dtype=np.float64).reshape(3)
        if G.is_multigraph():
            edges = list(G.edges(keys=True, data=True))
            if edges and all(isinstance(k, (int, np.integer)) for _, _, k, _ in edges) and \
                    len({k for _, _, k, _ in edges}) == len(edges):
                edges.sort(key=lambda t: t[2])
            edges = [(u, v, data) for u, v, _, data in edges]
        else:
            edges = list(G.edges(data=True))
        node_label_names = set(G.graph.get("node_labels", ()))
        edge_label_names = set(G.graph.get("edge_labels", ()))

        def split(records, skip, label_names, count):
            attrs, labels = {}, {}
            for i, rec in enumerate(records):
                for name, value in rec.items():
                    if name in skip or name.startswith("point_"):
                        continue
                    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
                        continue
                    is_label = name in label_names or (isinstance(value, (int, np.integer)) and name not in attrs)
                    target = labels if is_label else attrs
                    target.setdefault(name, np.zeros(count, dtype=np.int32 if is_label else np.float32))[i] = value
            return attrs, labels

        node_attrs, node_labels = split([G.nodes[n] for n in nodes], {"pos"}, node_label_names, len(nodes))
        pairs, points, point_attrs = [], [], {}
        for e, (u, v, data) in enumerate(edges):
            a, b = index[u], index[v]
            pts = data.get("points")
            pattr = {k[6:]: np.asarray(val, dtype=np.float32) for k, val in data.items() if k.startswith("point_")}
            if pts is not None:
                pts = np.asarray(pts, dtype=np.float64).reshape(-1, 3)
                # Undirected graphs may report an edge from its other end: the polyline says which
                # node the edge starts at, and it keeps its direction (and its point attributes).
                if a != b and not np.array_equal(pts[0], positions[a]) and np.array_equal(pts[0], positions[b]):
                    a, b = b, a
            else:
                pts = np.stack([positions[a], positions[b]])
            pairs.append((a, b))
            points.append(pts)
            for name, val in pattr.items():
                point_attrs.setdefault(name, [None] * len(edges))[e] = val
        for name, per_edge in point_attrs.items():
            for e, val in enumerate(per_edge):
                if val is None:
                    per_edge[e] = np.zeros(len(points[e]), dtype=np.float32)
        edge_attrs, edge_labels = split([data for _, _, data in edges], {"points"}, edge_label_names, len(edges))
        return cls.from_arrays(positions, np.asarray(pairs, dtype=np.int64).reshape(-1, 2), points,
                               node_attrs, node_labels, edge_attrs, edge_labels, point_attrs,
                               G.graph.get("source_grid"))


def branch_table(G) -> Dict[str, np.ndarray]:
    """skan's branch summary for a graph (a networkx graph from Graph.to_networkx, or a Graph):
    one row per edge with skeleton_id (connected component), node_id_src, node_id_dst,
    branch_distance (polyline length), branch_type (0 endpoint-endpoint, 1 junction-endpoint,
    2 junction-junction, 3 isolated cycle), euclidean_distance between the end nodes and, when the
    edges carry `point_radius`, mean_radius. Degrees count a loop twice, as networkx does."""
    import networkx as nx

    if isinstance(G, Graph):
        G = G.to_networkx()
    component = {}
    for c, nodes in enumerate(nx.connected_components(nx.Graph(G))):
        for n in nodes:
            component[n] = c
    rows = list(G.edges(keys=True, data=True)) if G.is_multigraph() else \
        [(u, v, None, d) for u, v, d in G.edges(data=True)]
    if rows and all(isinstance(k, (int, np.integer)) for _, _, k, _ in rows):
        rows.sort(key=lambda t: t[2])
    out = {k: [] for k in ("skeleton_id", "node_id_src", "node_id_dst", "branch_distance", "branch_type",
                           "euclidean_distance")}
    radii = []
    for u, v, _, d in rows:
        pts = np.asarray(d.get("points", np.stack([G.nodes[u]["pos"], G.nodes[v]["pos"]])), dtype=np.float64)
        if not np.array_equal(pts[0], np.asarray(G.nodes[u]["pos"], dtype=np.float64)):
            u, v = v, u
        du, dv = G.degree(u), G.degree(v)
        if u == v and du == 2:
            kind = 3
        elif du == 1 and dv == 1:
            kind = 0
        elif du == 1 or dv == 1:
            kind = 1
        else:
            kind = 2
        out["skeleton_id"].append(component[u])
        out["node_id_src"].append(u)
        out["node_id_dst"].append(v)
        out["branch_distance"].append(float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum()))
        out["branch_type"].append(kind)
        out["euclidean_distance"].append(float(np.linalg.norm(pts[-1] - pts[0])))
        if "point_radius" in d:
            radii.append(float(np.mean(d["point_radius"])))
    table = {k: np.asarray(v, dtype=np.float64 if "distance" in k else np.int64) for k, v in out.items()}
    if rows and len(radii) == len(rows):
        table["mean_radius"] = np.asarray(radii)
    return table


# ---------------------------------------------------------------- conversions
def _to_data(obj: Any, what: str) -> Data:
    if isinstance(obj, Data):
        return obj
    if isinstance(obj, Graph):
        return obj._data
    if isinstance(obj, Table):
        return obj._to_data()
    if isinstance(obj, np.ndarray):
        return _volume_to_data(obj)
    try:
        import networkx as nx
        if isinstance(obj, nx.Graph):
            return Graph.from_networkx(obj)._data
    except ImportError:  # pragma: no cover
        pass
    if isinstance(obj, Mapping):
        return Table(obj)._to_data()
    raise InputError(f"{what}: cannot pass a {type(obj).__name__} to Skelflow "
                     "(a NumPy volume, a Graph, a networkx graph, a Table or a dict of columns)")


def _from_data(d: Data):
    t = d.type_id
    if t.startswith("volume."):
        return _data_to_volume(d)
    if t == "graph":
        return Graph(d)
    if t == "table":
        return Table._from_data(d)
    return d


# ---------------------------------------------------------------- pipelines
class Pipeline:
    """A pipeline: the same model and YAML as the GUI and `skelflow run`.

        p = skelflow.Pipeline()
        p.add_node("phantom", "synthetic.network", shape="rods", size=[64, 64, 64])
        p.add_node("seg", "segmentation.threshold", low=0.5)
        p.connect("phantom.image", "seg.image")
        p.save("my.yaml"); outputs = p.run(threads=2)
    """

    def __init__(self, path: Optional[os.PathLike] = None):
        self._p = _core.Pipeline.load(os.fspath(path)) if path is not None else _core.Pipeline()

    @classmethod
    def load(cls, path) -> "Pipeline":
        return cls(path)

    @classmethod
    def parse(cls, text: str, file_name: str = "<string>", base_dir=".") -> "Pipeline":
        p = cls()
        p._p = _core.Pipeline.parse(text, file_name, os.fspath(base_dir))
        return p

    def add_node(self, name: str, module: str, **params) -> str:
        """Adds node `name` running `module` with the given parameters; returns the name."""
        self._p.add_node(name, module)
        for k, v in params.items():
            self._p.set_param(name, k, _param_value(v))
        return name

    def set(self, node: str, **params) -> None:
        """Sets parameters of a node."""
        for k, v in params.items():
            self._p.set_param(node, k, _param_value(v))

    def connect(self, source: str, target: str) -> None:
        """Connects output `source` ("node.port") to input `target` ("node.port")."""
        self._p.connect(source, target)

    def remove_node(self, name: str) -> None:
        self._p.remove_node(name)

    @property
    def nodes(self) -> Dict[str, dict]:
        """node id -> {"module", "params", "inputs"} (explicitly set parameters only)."""
        return {n: {"module": self._p.node_module(n), "params": self._p.node_params(n),
                    "inputs": self._p.node_inputs(n)} for n in self._p.node_ids()}

    @property
    def file(self) -> str:
        return self._p.file

    def to_yaml(self) -> str:
        return self._p.to_yaml()

    def save(self, path) -> None:
        """Writes the canonical YAML (atomically), the format `skelflow run` and the GUI read."""
        self._p.save(os.fspath(path))

    def validate(self) -> list:
        """Every problem `skelflow validate` would report, one message each (empty when valid)."""
        return list(self._p.validate())

    def run(self, **kwargs) -> Dict[str, Any]:
        """Same as skelflow.run(self, ...)."""
        return run(self, **kwargs)

    def __eq__(self, other) -> bool:
        return isinstance(other, Pipeline) and self._p == other._p

    def __repr__(self) -> str:
        return f"<skelflow.Pipeline {self.file}: {', '.join(self._p.node_ids())}>"


def _param_value(v):
    if isinstance(v, os.PathLike):
        return os.fspath(v)
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, np.generic):
        return v.item()
    return v


def run(pipeline, set: Optional[Mapping[str, Any]] = None, inputs: Optional[Mapping[str, Any]] = None,
        threads: int = 0, output_dir=None, targets: Optional[Iterable[str]] = None,
        outputs: Optional[Iterable[str]] = None, allow_outside_output_dir: bool = False) -> Dict[str, Any]:
    """Runs a pipeline (a YAML file path or a Pipeline) through the executor `skelflow run` uses and
    returns its outputs: {"node.port": Volume | Graph | Table | Data}.

    set:     {"node.param": value}, like `--set node.param=value` (same messages).
    inputs:  {"node.port": data}: the node's outputs are the data given (a NumPy volume, Graph,
             networkx graph, Table...) instead of running it, e.g. {"read.volume": array}.
    threads: thread budget (0 = all cores). output_dir, targets, allow_outside_output_dir: as
             --output-dir, --target, --allow-outside-output-dir. outputs: the "node.port" keys to
             return (all outputs of the nodes that ran when not given).
    Files are written as by the CLI: all at once when the run succeeds, none otherwise. Ctrl+C
    cancels the run (KeyboardInterrupt). Errors raise skelflow.InputError / skelflow.Error.
    """
    if isinstance(pipeline, Pipeline):
        p = pipeline._p
    else:
        p = _core.Pipeline.load(os.fspath(pipeline))
    given = {k: _to_data(v, f"inputs: '{k}'") for k, v in (inputs or {}).items()}
    sets = {k: _param_value(v) for k, v in (set or {}).items()}
    result = _core.run(p, sets, given, int(threads), os.fspath(output_dir) if output_dir is not None else "",
                       bool(allow_outside_output_dir), list(targets or []),
                       list(outputs) if outputs is not None else None)
    return {k: _from_data(v) for k, v in result.items()}


def last_report() -> Optional[dict]:
    """The run report of the last skelflow.run or module function call in this process, as
    `skelflow run --report` writes it (per node: seconds, peak memory, files written, warnings);
    None before the first run."""
    import json

    text = _core.last_report()
    return json.loads(text) if text else None


# ---------------------------------------------------------------- modules as functions
_OPTION_NAMES = ("threads", "output_dir")


class Outputs(dict):
    """The outputs of a module with several: a dict by port name whose ports are also attributes
    (`skelflow.modules.thinning.doht(...).skeleton`)."""

    def __getattr__(self, name):
        try:
            return self[name]
        except KeyError:
            raise AttributeError(f"no output '{name}' (outputs: {', '.join(self)})") from None

    def __dir__(self):
        return list(super().__dir__()) + list(self)


def _param_doc(p: dict) -> str:
    kind = p["type"]
    parts = []
    if p["choices"]:
        parts.append("one of " + ", ".join(repr(c) for c in p["choices"]))
    if p["min"] is not None or p["max"] is not None:
        lo = "-inf" if p["min"] is None else f"{p['min']:g}"
        hi = "inf" if p["max"] is None else f"{p['max']:g}"
        parts.append(f"range [{lo}, {hi}]")
    if p["list_length"] >= 0:
        parts.append(f"{p['list_length']} values")
    if p["unit"]:
        parts.append(f"unit {p['unit']}")
    if p["path_role"]:
        parts.append(f"{p['path_role']} file" + (" (" + ", ".join(p["extensions"]) + ")" if p["extensions"] else ""))
    default = p["default"]
    if default == "" or default == []:
        parts.append("not set by default" if p["optional"] else "required")
    else:
        parts.append(f"default {default!r}")
    return f"    {p['name']} ({kind}; {'; '.join(parts)}): {p['doc']}"


def _module_doc(spec: dict) -> str:
    lines = [spec["doc"], ""]
    if spec["inputs"]:
        lines.append("Inputs (NumPy volumes, Graph, Table; positional or by name):")
        for p in spec["inputs"]:
            req = "required" if p["required"] else "optional"
            lines.append(f"    {p['name']} ({', '.join(p['types'])}; {req}): {p['doc']}")
        lines.append("")
    if spec["params"]:
        lines.append("Parameters (by name):")
        lines.extend(_param_doc(p) for p in spec["params"])
        lines.append("")
    lines.append("Options: threads (0 = all cores), output_dir (where relative output paths go).")
    lines.append("")
    outs = spec["outputs"]
    if not outs:
        lines.append("Returns None (the module writes files).")
    elif len(outs) == 1:
        o = outs[0]
        lines.append(f"Returns: {o['name']} ({', '.join(o['types'])}): {o['doc']}")
    else:
        lines.append("Returns skelflow.Outputs, a dict of its outputs by port name (also attributes):")
        for o in outs:
            lines.append(f"    {o['name']} ({', '.join(o['types'])}): {o['doc']}")
    if spec["details"]:
        lines += ["", spec["details"]]
    return "\n".join(lines)


def _make_function(spec: dict):
    name = spec["name"]
    in_names = [p["name"] for p in spec["inputs"]]
    out_names = [p["name"] for p in spec["outputs"]]

    def call(*args, **kwargs):
        if len(args) > len(in_names):
            raise TypeError(f"{name}() takes {len(in_names)} inputs positionally ({', '.join(in_names)}); "
                            f"{len(args)} given")
        inputs = dict(zip(in_names, args))
        threads = kwargs.pop("threads", 0)
        output_dir = kwargs.pop("output_dir", None)
        params = {}
        for k, v in kwargs.items():
            if k in in_names:
                if k in inputs:
                    raise TypeError(f"{name}() got input '{k}' twice")
                inputs[k] = v
            else:
                params[k] = _param_value(v)
        given = {k: _to_data(v, f"{name}: input '{k}'") for k, v in inputs.items() if v is not None}
        result = _core.run_module(name, given, params, int(threads),
                                  os.fspath(output_dir) if output_dir is not None else "")
        converted = {k: _from_data(v) for k, v in result.items()}
        if not out_names:
            return None
        if len(out_names) == 1:
            return converted.get(out_names[0])
        return Outputs((k, converted[k]) for k in out_names if k in converted)

    params = []
    for p in spec["inputs"]:
        default = inspect.Parameter.empty if p["required"] else None
        params.append(inspect.Parameter(p["name"], inspect.Parameter.POSITIONAL_OR_KEYWORD, default=default))
    for p in spec["params"]:
        if p["name"].isidentifier() and not keyword.iskeyword(p["name"]) and p["name"] not in in_names \
                and p["name"] not in _OPTION_NAMES:
            params.append(inspect.Parameter(p["name"], inspect.Parameter.KEYWORD_ONLY, default=p["default"]))
    params.append(inspect.Parameter("threads", inspect.Parameter.KEYWORD_ONLY, default=0))
    params.append(inspect.Parameter("output_dir", inspect.Parameter.KEYWORD_ONLY, default=None))
    call.__signature__ = inspect.Signature(params)
    short = name.split(".", 1)[1]
    call.__name__ = short
    call.__qualname__ = name
    call.__module__ = "skelflow.modules." + spec["family"]
    call.__doc__ = _module_doc(spec)
    call.spec = spec
    return call


def _build_modules():
    root = types.ModuleType("skelflow.modules", "Every Skelflow module as a function, by family "
                            "(generated from the module specs at import time).")
    root.__path__ = []  # a package, so `import skelflow.modules.thinning` works
    names = []
    for spec in _core.specs():
        family, short = spec["name"].split(".", 1)
        fam = getattr(root, family, None)
        if fam is None:
            fam = types.ModuleType("skelflow.modules." + family, f"The {family} modules.")
            setattr(root, family, fam)
            sys.modules[fam.__name__] = fam
        setattr(fam, short, _make_function(spec))
        names.append(spec["name"])
    sys.modules[root.__name__] = root
    return root, names


def _load_plugins():
    """Loads the plugins (SKELFLOW_PLUGIN_PATH, the user folder) so their modules become functions
    too; a refused plugin is a warning naming its file and why."""
    import warnings
    loaded, errors = _core.load_plugins()
    for e in errors:
        warnings.warn("skelflow: " + e, RuntimeWarning, stacklevel=3)
    return loaded


_plugins = _load_plugins()


def plugins() -> list:
    """The plugins loaded at import: [(file, [module names])]."""
    return [(f, list(m)) for f, m in _plugins]


modules, _module_names = _build_modules()


def module_names() -> list:
    """The names of every registered module ("family.name"), sorted."""
    return list(_module_names)
