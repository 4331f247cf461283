"""Graphs to networkx and back, and skan's branch table of a known graph."""
import networkx as nx
import numpy as np
import pytest

import skelflow


def known_graph():
    """A Y (junction 0 with branches to 1 (bent), 2 and 3), a separate segment 4-5 and a ring
    hanging on node 6 (a loop edge)."""
    positions = [(0, 0, 0), (2, 0, 0), (0, 3, 0), (-4, 0, 0), (10, 0, 0), (10, 5, 0), (20, 0, 0)]
    edges = [(0, 1), (0, 2), (3, 0), (4, 5), (6, 6)]
    points = [
        np.array([(0, 0, 0), (1, 1, 0), (2, 0, 0)], float),
        np.array([(0, 0, 0), (0, 3, 0)], float),
        np.array([(-4, 0, 0), (-2, 0, 0), (0, 0, 0)], float),
        np.array([(10, 0, 0), (10, 5, 0)], float),
        np.array([(20, 0, 0), (21, 0, 0), (21, 1, 0), (20, 1, 0), (20, 0, 0)], float),
    ]
    radius = [np.array([1.0, 2.0, 3.0], np.float32), np.array([1.0, 1.0], np.float32),
              np.array([2.0, 2.0, 2.0], np.float32), np.array([0.5, 1.5], np.float32),
              np.array([1.0, 1.0, 1.0, 1.0, 1.0], np.float32)]
    return skelflow.Graph.from_arrays(
        positions, edges, points,
        node_labels={"kind": np.array([2, 1, 1, 1, 1, 1, 3], np.int32)},
        edge_attributes={"tortuosity": np.array([1.41, 1.0, 1.0, 1.0, 0.0], np.float32)},
        point_attributes={"radius": radius})


def test_branch_table_of_a_known_graph():
    G = known_graph().to_networkx()
    t = skelflow.branch_table(G)
    np.testing.assert_array_equal(t["node_id_src"], [0, 0, 3, 4, 6])
    np.testing.assert_array_equal(t["node_id_dst"], [1, 2, 0, 5, 6])
    np.testing.assert_allclose(t["branch_distance"], [2 * np.sqrt(2), 3, 4, 5, 4])
    np.testing.assert_allclose(t["euclidean_distance"], [2, 3, 4, 5, 0])
    # junction-endpoint x3, endpoint-endpoint, isolated cycle
    np.testing.assert_array_equal(t["branch_type"], [1, 1, 1, 0, 3])
    np.testing.assert_array_equal(t["skeleton_id"], [0, 0, 0, 1, 2])
    np.testing.assert_allclose(t["mean_radius"], [2, 1, 2, 1, 1])


def test_networkx_has_positions_points_radii_and_attributes():
    G = known_graph().to_networkx()
    assert isinstance(G, nx.MultiGraph)
    assert G.number_of_nodes() == 7 and G.number_of_edges() == 5
    np.testing.assert_array_equal(G.nodes[6]["pos"], [20, 0, 0])
    assert G.nodes[0]["kind"] == 2 and isinstance(G.nodes[0]["kind"], int)
    e = G.edges[0, 1, 0]
    assert e["points"].shape == (3, 3)
    np.testing.assert_allclose(e["point_radius"], [1, 2, 3])
    assert e["tortuosity"] == pytest.approx(1.41)
    assert G.degree(6) == 2  # the ring's loop counts twice
    assert G.graph["node_labels"] == ["kind"]


def test_networkx_round_trip_is_exact():
    g = known_graph()
    back = skelflow.Graph.from_networkx(g.to_networkx())
    a, b = g.arrays(), back.arrays()
    np.testing.assert_array_equal(a["positions"], b["positions"])
    np.testing.assert_array_equal(a["edges"], b["edges"])
    for pa, pb in zip(a["points"], b["points"]):
        np.testing.assert_array_equal(pa, pb)
    for key in ("node_attributes", "node_labels", "edge_attributes", "edge_labels"):
        assert a[key].keys() == b[key].keys()
        for name in a[key]:
            np.testing.assert_array_equal(a[key][name], b[key][name])
            assert a[key][name].dtype == b[key][name].dtype
    for pa, pb in zip(a["point_attributes"]["radius"], b["point_attributes"]["radius"]):
        np.testing.assert_array_equal(pa, pb)


def test_from_networkx_orients_polylines_and_refuses_bad_graphs():
    G = nx.Graph()
    G.add_node("b", pos=(1.0, 0.0, 0.0))
    G.add_node("a", pos=(0.0, 0.0, 0.0))
    # Stored from "a" to "b", while networkx reports the edge as (b, a).
    G.add_edge("a", "b", points=np.array([(0, 0, 0), (0.5, 0.5, 0), (1, 0, 0)], float), point_radius=[1, 2, 3])
    g = skelflow.Graph.from_networkx(G).arrays()
    np.testing.assert_array_equal(g["edges"], [[1, 0]])  # from "a" (node 1) to "b" (node 0)
    np.testing.assert_array_equal(g["points"][0][0], g["positions"][1])
    np.testing.assert_allclose(g["point_attributes"]["radius"][0], [1, 2, 3])
    H = nx.Graph()
    H.add_node(0, pos=(0, 0, 0))
    H.add_node(1, pos=(1, 0, 0))
    H.add_edge(0, 1, points=np.array([(0, 0, 0), (5, 5, 5)], float))
    with pytest.raises(skelflow.InputError, match="not a valid graph"):
        skelflow.Graph.from_networkx(H)
    K = nx.Graph()
    K.add_node(0)
    with pytest.raises(skelflow.InputError, match="no 'pos'"):
        skelflow.Graph.from_networkx(K)


def test_graph_from_a_module_to_networkx_and_back_into_a_module():
    mask = np.zeros((24, 24, 40), np.uint8)
    mask[10:14, 10:14, 4:36] = 1  # a rod along x
    dist = skelflow.modules.distance.euclidean(mask=mask)
    skel = skelflow.modules.thinning.doht(mask=mask, priority=dist).skeleton
    graph = skelflow.modules.geometry.skeleton_to_graph(skeleton=skel, distance=dist).graph
    G = graph.to_networkx()
    assert G.number_of_edges() >= 1
    t = skelflow.branch_table(G)
    assert t["branch_distance"].max() > 20  # most of the rod's 32 voxels
    # A networkx graph goes into a module as it is.
    stats = skelflow.modules.analysis.network_statistics(graph=G)
    assert isinstance(stats, dict) and isinstance(stats["summary"], skelflow.Table)
