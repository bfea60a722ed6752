"""merge-tree and contour-tree through the client: the Tree built from hand-made arrays (global
NodeIds over several components, the branches, the digests, the checks), then against a server:
upstream TTK's digests computed from the streamed arrays (on the fields, on the fields
simplified, on a mesh of two components), the invariants of the three trees on a sample, their
branches against the persistence diagram, a threshold, several components, files equal to
actopo-bench's, networkx, the plot and `actopo run merge-tree --plot`. The first tests need no
server."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import matplotlib.image
import meshio
import numpy as np
import pytest
import pyvista as pv
from harness import BENCH_BIN, REPO
from meshes import lattice
from references import CASE_IDS, CASES, sha256_lines, ttk

import actopo
from actopo._tree import from_arrays
from actopo.types import Tree

KINDS = {"join": ("merge-tree", {}), "split": ("merge-tree", {"tree": "split"}),
         "contour": ("contour-tree", {})}
"""Each tree: the algorithm and the parameters that give it."""
SAMPLE = "wavelet:12"
TREES_TTK = REPO / "tests" / "ttk_reference" / "trees-ttk.json"
"""Upstream TTK's trees with every array digested (tests/ttk_reference/trees_reference.py): on
the simplified fields, and on fertility twice, two components."""


def _wire(kind: str, components: list[tuple[list[tuple[int, float, int]], list[tuple[int, int]]]],
          vertex_arc: list[int]) -> dict[str, dict[str, np.ndarray]]:
    """The groups the server streams for a tree whose components are (nodes, arcs): nodes
    (vertex, value, CriticalType) in NodeId order, arcs (down, up) in the component's own ids,
    as TTK writes them, with the server's ComponentId per node and per arc. Vertex v lies on
    arc vertex_arc[v] (an index over all the arcs); node i's vertex is at (vertex, vertex / 2,
    0)."""
    nodes = [node for c in components for node in c[0]]
    first = np.cumsum([0] + [len(c[0]) for c in components])
    ends, segmentation_ids, local, arc_component = [], [], [], []
    for k, (_, arcs) in enumerate(components):
        for i, (down, up) in enumerate(arcs):
            ends.append((down + first[k], up + first[k]))
            segmentation_ids.append(first[k] + i)
            local.append((down, up))
            arc_component.append(k)
    point_of: dict[int, int] = {}
    connectivity = []
    for down, up in ends:  # a point per node at its first use, the lower end first
        for node in ((up, down) if kind == "split" else (down, up)):
            point_of.setdefault(int(node), len(point_of))
            connectivity.append(point_of[int(node)])
    position = np.array([[v, v / 2, 0.0] for v, _, _ in nodes])
    a = len(ends)
    arc_size = np.array([vertex_arc.count(i) for i in range(a)], dtype=np.int32)
    return {
        "tree_nodes": {
            "Points": position, "NodeId": np.arange(len(nodes), dtype=np.int32),
            "Scalar": np.array([s for _, s, _ in nodes], dtype=np.float32),
            "VertexId": np.array([v for v, _, _ in nodes], dtype=np.int32),
            "CriticalType": np.array([t for _, _, t in nodes], dtype=np.int32),
            "RegionSize": np.arange(len(nodes), dtype=np.int32),
            "RegionSpan": np.ones(len(nodes), dtype=np.int32),
            "ComponentId": np.repeat(np.arange(len(components), dtype=np.int32),
                                     [len(c[0]) for c in components])},
        "tree_arcs": {
            "Points": position[sorted(point_of, key=point_of.__getitem__)],
            "Offsets": np.arange(0, 2 * a + 1, 2, dtype=np.int64),
            "Connectivity": np.array(connectivity, dtype=np.int64),
            "SegmentationId": np.array(segmentation_ids, dtype=np.int32),
            "downNodeId": np.array([d for d, _ in local], dtype=np.int32),
            "upNodeId": np.array([u for _, u in local], dtype=np.int32),
            "RegionSize": arc_size, "RegionSpan": np.arange(a, dtype=np.float64),
            "ComponentId": np.array(arc_component, dtype=np.int32)},
        "segmentation": {
            "SegmentationId": np.array(segmentation_ids, dtype=np.int32)[vertex_arc],
            "RegionSize": arc_size[vertex_arc],
            "RegionSpan": np.zeros(len(vertex_arc)),
            "RegionType": np.zeros(len(vertex_arc), dtype=np.int8)},
    }


def _tree(kind: str, wire: dict[str, dict[str, np.ndarray]]) -> Tree:
    return from_arrays(kind, wire["tree_nodes"], wire["tree_arcs"], wire["segmentation"])


# A join tree over three components: two minima (vertices 10, 11) merging at 12 below the root
# 13; a one-vertex component (20, a self-loop); a minimum 30 below its root 31.
JOIN = [([(10, 0.0, 0), (11, 1.0, 0), (12, 2.0, 1), (13, 5.0, 3)], [(0, 2), (1, 2), (2, 3)]),
        ([(20, 3.0, 5)], [(0, 0)]),
        ([(30, 1.0, 0), (31, 4.0, 3)], [(0, 1)])]
JOIN_VERTEX_ARC = [0] * 11 + [1] + [2] * 8 + [3] + [4] * 11  # 32 vertices


def test_component_ids_become_global_node_ids():
    tree = _tree("join", _wire("join", JOIN, JOIN_VERTEX_ARC))
    assert repr(tree) == "Tree('join', 7 nodes, 5 arcs, 3 components)"
    assert tree.component_offsets.tolist() == [0, 4, 5, 7]
    assert tree.arcs.down.tolist() == [0, 1, 2, 4, 5] and tree.arcs.up.tolist() == [2, 2, 3, 4, 6]
    assert tree.arcs.component.tolist() == [0, 0, 0, 1, 2]
    assert tree.arcs.down.dtype == tree.arcs.up.dtype == np.int32
    assert tree.segmentation.arc.tolist() == JOIN_VERTEX_ARC
    assert tree.counts_by_type() == {"0": 3, "1": 1, "3": 2, "5": 1}
    assert len(tree.nodes) == 7 and len(tree.arcs) == 5 and len(tree.segmentation) == 32
    assert tree.largest_regions(2).tolist() == [0, 4] and tree.largest_regions(0).tolist() == []
    assert tree.region_vertices(1).tolist() == [11]


def test_arcs_in_any_order_take_their_components_first_node_id():
    """The global ids come from each arc's ComponentId, whatever the arcs' order: here the
    components' arcs interleaved, and no component's first arc naming its node 0."""
    wire = _wire("join", JOIN, JOIN_VERTEX_ARC)
    order = np.array([4, 2, 3, 1, 0])
    arcs = wire["tree_arcs"]
    for name in ("SegmentationId", "downNodeId", "upNodeId", "RegionSize", "RegionSpan",
                 "ComponentId"):
        arcs[name] = arcs[name][order]
    arcs["Connectivity"] = arcs["Connectivity"].reshape(-1, 2)[order].ravel()
    tree = _tree("join", wire)
    assert tree.arcs.down.tolist() == [5, 2, 4, 1, 0] and tree.arcs.up.tolist() == [6, 3, 4, 2, 2]
    assert tree.arcs.component.tolist() == [2, 0, 1, 0, 0]
    assert tree.arcs_sha256() == _tree("join", _wire("join", JOIN, JOIN_VERTEX_ARC)).arcs_sha256()


def test_digests_are_those_of_the_documented_lines():
    tree = _tree("join", _wire("join", JOIN, JOIN_VERTEX_ARC))
    assert tree.nodes_sha256() == sha256_lines(
        ["10 0\n", "11 0\n", "12 1\n", "13 3\n", "20 5\n", "30 0\n", "31 3\n"])
    assert tree.arcs_sha256() == sha256_lines(
        ["10 12\n", "11 12\n", "12 13\n", "20 20\n", "30 31\n"])
    ends = {0: "10 12", 1: "11 12", 2: "12 13", 3: "20 20", 4: "30 31"}
    assert tree.segmentation_sha256() == sha256_lines(
        f"{v} {ends[arc]}\n" for v, arc in enumerate(JOIN_VERTEX_ARC))


def test_branches_follow_the_elder_rule():
    join = _tree("join", _wire("join", JOIN, JOIN_VERTEX_ARC)).branches()
    # The younger minimum (11) ends at the saddle; each component keeps one infinite branch.
    assert list(zip(join.leaf.tolist(), join.end.tolist(), join.persistence.tolist(),
                    join.is_finite.tolist(), strict=True)) == [
        (0, 3, 5.0, False), (5, 6, 3.0, False), (1, 2, 1.0, True), (4, 4, 0.0, False)]
    # A split tree: maxima 0 (value 5) and 1 (4) merge at 2 (3) above the root 3 (0).
    split = _tree("split", _wire("split", [([(0, 5.0, 3), (1, 4.0, 3), (2, 3.0, 2),
                                             (3, 0.0, 0)], [(0, 2), (1, 2), (2, 3)])],
                                  [0, 1, 2, 2])).branches()
    assert (split.leaf.tolist(), split.end.tolist(), split.is_finite.tolist()) == (
        [0, 1], [3, 2], [False, True])
    # A contour tree: maxima A (node 0, value 10) and B (2, 8) meet at the split saddle S (1, 6),
    # minima m1 (4, 0) and m2 (5, 1) at the join saddle J (3, 4): both sweeps' branches.
    contour = _tree("contour", _wire(
        "contour", [([(0, 10.0, 3), (1, 6.0, 2), (2, 8.0, 3), (3, 4.0, 1), (4, 0.0, 0),
                      (5, 1.0, 0)], [(1, 0), (1, 2), (3, 1), (4, 3), (5, 3)])],
        [0, 0, 1, 2, 3, 4])).branches()
    assert list(zip(contour.leaf.tolist(), contour.end.tolist(), contour.persistence.tolist(),
                    contour.is_finite.tolist(), strict=True)) == [
        (4, 0, 10.0, False), (5, 3, 3.0, True), (2, 1, 2.0, True)]


def test_to_networkx_is_a_forest_of_the_components():
    networkx = pytest.importorskip("networkx")
    tree = _tree("join", _wire("join", JOIN, JOIN_VERTEX_ARC))
    graph = tree.to_networkx()
    assert isinstance(graph, networkx.DiGraph) and graph.graph["kind"] == "join"
    assert sorted(graph.edges) == [(0, 2), (1, 2), (2, 3), (5, 6)]  # no self-loop
    assert networkx.number_weakly_connected_components(graph) == 3
    assert networkx.is_forest(graph)
    assert graph.nodes[2] == {"vertex": 12, "scalar": 2.0, "critical_type": 1, "region_size": 2,
                              "region_span": 1, "position": (12.0, 6.0, 0.0)}
    assert graph.edges[2, 3] == {"arc": 2, "segmentation_id": 2, "region_size": 8,
                                 "region_span": 2.0}
    assert (4, 4) in tree.to_networkx(self_loops=True).edges


def test_to_networkx_names_networkx_when_missing(monkeypatch):
    monkeypatch.setitem(sys.modules, "networkx", None)  # as if networkx were not installed
    tree = _tree("join", _wire("join", JOIN, JOIN_VERTEX_ARC))
    with pytest.raises(ImportError, match="needs networkx: pip install networkx"):
        tree.to_networkx()


def test_plot_puts_nodes_at_their_values_and_writes_the_persistence(tmp_path):
    tree = _tree("join", _wire("join", JOIN, JOIN_VERTEX_ARC))
    ax = tree.plot(annotate=2)
    heights = np.concatenate([c.get_offsets()[:, 1] for c in ax.collections[1:]])
    assert sorted(heights.tolist()) == sorted(tree.nodes.scalar.tolist())
    assert [t.get_text() for t in ax.texts] == ["5 (inf)", "3 (inf)"]
    assert ax.get_legend_handles_labels()[1] == ["minimum (3)", "1-saddle (1)", "maximum (2)",
                                                 "regular (1)"]
    assert ax.get_title() == "join tree: 7 nodes, 5 arcs" and ax.get_ylabel() == "scalar"
    path = tree.save_plot(tmp_path / "join.svg", title="three components")
    assert Path(path).read_text().startswith("<?xml")


@pytest.mark.parametrize("change,message", [
    (lambda w: w["tree_nodes"].pop("ComponentId"),
     "tree_nodes/ComponentId: missing from the job's arrays; the server streams it"),
    (lambda w: w["tree_arcs"].pop("ComponentId"),
     "tree_arcs/ComponentId: missing from the job's arrays; the server streams it"),
    (lambda w: w["tree_nodes"].update(ComponentId=np.zeros(6, dtype=np.int32)),
     "tree_nodes/ComponentId: 6 values, expected 7"),
    (lambda w: w["tree_arcs"].update(ComponentId=np.array([0, 0, 0, 1], dtype=np.int32)),
     "tree_arcs/ComponentId: 4 values, expected 5"),
    (lambda w: w["tree_nodes"].update(ComponentId=np.array([0, 0, 0, 0, 1, 2, 2.0])),
     "tree_nodes/ComponentId: dtype float64 is not an integer type"),
    (lambda w: w["tree_nodes"].update(ComponentId=np.array([0, 0, 0, 0, 2, 1, 1],
                                                           dtype=np.int32)),
     "tree_nodes/ComponentId: not 0, 1, 2, ... over NodeId"),
    (lambda w: w["tree_nodes"].update(ComponentId=np.array([1, 1, 1, 1, 2, 3, 3],
                                                           dtype=np.int32)),
     "tree_nodes/ComponentId: not 0, 1, 2, ... over NodeId"),
    (lambda w: w["tree_arcs"].update(ComponentId=np.array([0, 0, 0, 1, 3], dtype=np.int32)),
     r"tree_arcs/ComponentId: arc 4 is in component 3, but tree_nodes/ComponentId has 3"),
    (lambda w: w["tree_arcs"].update(upNodeId=np.array([2, 2, 3, 0, 2], dtype=np.int32)),
     r"tree_arcs/upNodeId: arc 4 has 2, not within the 2 nodes of its component \(2\)"),
    (lambda w: w["tree_arcs"].update(downNodeId=np.array([0, -1, 2, 0, 0], dtype=np.int32)),
     r"tree_arcs/downNodeId: arc 1 has -1, not within the 4 nodes of its component \(0\)"),
    (lambda w: w["segmentation"]["SegmentationId"].__setitem__(0, 3),
     "segmentation/SegmentationId: a vertex's id is no arc's"),
    (lambda w: w["tree_nodes"].pop("CriticalType"), "tree_nodes/CriticalType: missing"),
])
def test_a_layout_the_client_cannot_read_is_named(change, message):
    wire = _wire("join", JOIN, JOIN_VERTEX_ARC)
    change(wire)
    with pytest.raises(actopo.ActopoError, match=message):
        _tree("join", wire)
    with pytest.raises(actopo.ActopoError, match="tree: unknown kind 'forest'"):
        _tree("forest", _wire("join", JOIN, JOIN_VERTEX_ARC))


# Against the server.


def _run(session: actopo.Session, kind: str, **options) -> actopo.JobResult:
    algorithm, parameters = KINDS[kind]
    return session.run(algorithm, parameters={**parameters, **options.pop("parameters", {})},
                       **options)


@pytest.mark.parametrize("kind", list(KINDS))
@pytest.mark.parametrize("file,field", CASES, ids=CASE_IDS)
def test_digests_from_the_arrays_equal_ttks(client, meshes, file, field, kind):
    """The nodes, arcs and segmentation digested here from the streamed arrays (the arcs' ends
    as global NodeIds) equal upstream TTK's, and so do the counts."""
    expected = ttk(file, field)["merge_trees"][f"{kind}_tree"]
    with client.open_session(meshes(file), scalar=field, structure="compact") as session:
        result = _run(session, kind, digests=True)
    tree = result.tree
    assert tree is not None and tree.kind == kind == result.summary["tree"]
    assert (len(tree.nodes), len(tree.arcs)) == (expected["nodes"], expected["arcs"])
    assert tree.counts_by_type() == expected["critical_types"] == result.summary["critical_types"]
    for name in ("nodes_sha256", "arcs_sha256", "segmentation_sha256"):
        assert getattr(tree, name)() == expected[name] == result.summary[name], name


@pytest.fixture(scope="module")
def sample(client):
    """The sample's three trees, its persistence diagram and its field, on one session."""
    mesh = client.sample(SAMPLE)
    field = client.download_mesh(mesh, "all").point_data["RTData"]
    with client.open_session(mesh, structure="compact") as session:
        trees = {kind: _run(session, kind, digests=True) for kind in KINDS}
        diagram = session.run("persistence-diagram").diagram
    yield trees, diagram, field, mesh
    client.delete_mesh(mesh)


@pytest.mark.parametrize("kind", list(KINDS))
def test_arrays_have_ttks_shapes_and_types(sample, kind):
    result = sample[0][kind]
    tree = result.tree
    n, a, v = result.summary["nodes"], result.summary["arcs"], sample[3].vertices
    assert (len(tree.nodes), len(tree.arcs), len(tree.segmentation)) == (n, a, v)
    nodes, arcs, segmentation = tree.nodes, tree.arcs, tree.segmentation
    assert nodes.points.shape == (n, 3) and nodes.points.dtype == np.float64
    for values, dtype in ((nodes.node_id, np.int32), (nodes.vertex, np.int32),
                          (nodes.scalar, np.float32), (nodes.critical_type, np.int32),
                          (nodes.region_size, np.int32), (nodes.region_span, np.int32),
                          (arcs.down, np.int32), (arcs.up, np.int32),
                          (arcs.segmentation_id, np.int32), (arcs.region_size, np.int32),
                          (arcs.region_span, np.float64), (segmentation.segmentation_id, np.int32),
                          (segmentation.arc, np.int32), (segmentation.region_size, np.int32),
                          (segmentation.region_span, np.float64),
                          (segmentation.region_type, np.int8)):
        assert values.dtype == dtype
    wire = result.group("tree_arcs")
    assert wire["Offsets"].tolist() == list(range(0, 2 * a + 1, 2))
    assert set(result.groups) == {"tree_nodes", "tree_arcs", "segmentation"}
    assert tree.component_offsets.tolist() == [0, n]  # one component: global = local ids
    assert (arcs.down == wire["downNodeId"]).all() and (arcs.up == wire["upNodeId"]).all()


@pytest.mark.parametrize("kind", list(KINDS))
def test_the_trees_invariants(sample, kind):
    result = sample[0][kind]
    tree, field = result.tree, sample[2]
    nodes, arcs, segmentation = tree.nodes, tree.arcs, tree.segmentation
    assert tree.nodes_sha256() == result.summary["nodes_sha256"]
    assert tree.arcs_sha256() == result.summary["arcs_sha256"]
    assert tree.segmentation_sha256() == result.summary["segmentation_sha256"]
    assert tree.counts_by_type() == result.summary["critical_types"]
    # A node's value is its vertex's; the vertices are distinct.
    np.testing.assert_array_equal(nodes.scalar, field[nodes.vertex].astype(np.float32))
    assert len(np.unique(nodes.vertex)) == len(nodes)
    # Every vertex lies on one arc: the arcs' inner vertices and the nodes are all of them.
    assert int(arcs.region_size.sum()) + len(nodes) == len(segmentation)
    assert set(segmentation.segmentation_id.tolist()) <= set(arcs.segmentation_id.tolist())
    np.testing.assert_array_equal(segmentation.region_size, arcs.region_size[segmentation.arc])
    np.testing.assert_array_equal(segmentation.region_span, arcs.region_span[segmentation.arc])
    inner = np.setdiff1d(np.arange(len(segmentation)), nodes.vertex)
    counts = np.bincount(segmentation.arc[inner], minlength=len(arcs))
    np.testing.assert_array_equal(counts, arcs.region_size)
    # An inner vertex's value lies between its arc's two ends.
    ends = np.stack([nodes.scalar[arcs.down], nodes.scalar[arcs.up]], axis=1)[segmentation.arc]
    values = field.astype(np.float32)
    assert ((values[inner] >= ends[inner].min(1)) & (values[inner] <= ends[inner].max(1))).all()
    # Arcs run from the leaf side: upwards in the join and contour trees, down in the split tree.
    lower, upper = (arcs.up, arcs.down) if kind == "split" else (arcs.down, arcs.up)
    assert (nodes.scalar[lower] <= nodes.scalar[upper]).all()
    degree = np.bincount(np.concatenate([arcs.down, arcs.up]), minlength=len(nodes))
    if kind == "contour":
        # The leaves are the minima and the maxima, each with one arc.
        leaves = np.flatnonzero(degree == 1)
        assert set(nodes.critical_type[leaves].tolist()) == {0, 3}
    else:
        # The leaves are never an up end and have one arc; all the others are, but the root.
        leaf_type = 0 if kind == "join" else 3
        leaves = np.setdiff1d(np.arange(len(nodes)), arcs.up)
        assert (nodes.critical_type[leaves] == leaf_type).all() and (degree[leaves] == 1).all()
        assert (nodes.critical_type == leaf_type).sum() == len(leaves)
    largest = tree.largest_regions(3)
    assert (np.diff(arcs.region_size[largest]) <= 0).all()
    assert arcs.region_size[largest[0]] == arcs.region_size.max()
    assert len(tree.region_vertices(int(largest[0]))) >= arcs.region_size[largest[0]]


@pytest.mark.parametrize("kind", list(KINDS))
def test_to_networkx_is_a_tree(sample, kind):
    networkx = pytest.importorskip("networkx")
    tree = sample[0][kind].tree
    graph = tree.to_networkx()
    assert graph.number_of_nodes() == len(tree.nodes)
    assert graph.number_of_edges() == len(tree.nodes) - 1 == len(tree.arcs)
    assert networkx.is_tree(graph) and networkx.number_of_selfloops(graph) == 0
    if kind != "contour":  # every arc leads towards the root
        root = int(tree.branches().end[~tree.branches().is_finite][0])
        assert networkx.is_arborescence(graph.reverse()) and graph.out_degree(root) == 0
    node = int(tree.nodes.vertex.argmax())
    assert graph.nodes[node]["vertex"] == tree.nodes.vertex[node]


def test_join_branches_are_the_diagrams_minimum_pairs(sample, client, meshes):
    """The join tree's elder rule pairs each minimum with the saddle where it dies, as the
    persistence diagram's type-0 pairs do; its infinite branch is the infinite pair."""
    cases = [(sample[0]["join"].tree, sample[1])]
    with client.open_session(meshes("fertility_tet.vtu"), scalar="height",
                             structure="compact") as session:
        cases.append((session.run("merge-tree").tree, session.run("persistence-diagram").diagram))
    for tree, diagram in cases:
        branches = tree.branches()
        vertex = tree.nodes.vertex
        pairs = set(zip(vertex[branches.leaf[branches.is_finite]].tolist(),
                        vertex[branches.end[branches.is_finite]].tolist(), strict=True))
        minima = (diagram.pair_type == 0) & diagram.is_finite
        assert pairs == set(zip(diagram.birth_vertex[minima].tolist(),
                                diagram.death_vertex[minima].tolist(), strict=True))
        infinite = (diagram.pair_type == 0) & ~diagram.is_finite
        assert (vertex[branches.leaf[~branches.is_finite]].tolist(),
                vertex[branches.end[~branches.is_finite]].tolist()) == (
            diagram.birth_vertex[infinite].tolist(), diagram.death_vertex[infinite].tolist())
        assert (np.diff(branches.persistence) <= 0).all()
        assert len(branches) == (tree.nodes.critical_type == 0).sum()


def test_a_threshold_simplifies_first(client):
    mesh = client.sample(SAMPLE)
    try:
        with client.open_session(mesh, structure="compact") as session:
            for kind in ("join", "contour"):
                full = _run(session, kind).tree
                result = _run(session, kind, parameters={"relative_threshold": "0.05"})
                tree = result.tree
                assert len(tree.nodes) < len(full.nodes) and len(tree.arcs) < len(full.arcs)
                assert result.summary["simplification"]["removed_pairs"] > 0
                # The tree is the simplified field's: its nodes' values are that field's.
                simplified = result.simplified
                assert simplified is not None
                np.testing.assert_array_equal(
                    tree.nodes.scalar, simplified.values[tree.nodes.vertex].astype(np.float32))
                finite = tree.branches().is_finite
                assert (tree.branches().persistence[finite]
                        >= result.summary["simplification"]["threshold"] * (1 - 1e-6)).all()
    finally:
        client.delete_mesh(mesh)


def test_several_components_get_global_node_ids(client):
    """Three lattices apart: TTK's ids restart in each, the client's are global, and the
    digests computed from them equal the server's."""
    parts = [lattice(n) for n in (4, 3, 5)]
    firsts = np.cumsum([0] + [len(p[0]) for p in parts])
    points = np.vstack([p[0] + 5 * k for k, p in enumerate(parts)])
    tetrahedra = np.vstack([p[1] + firsts[k] for k, p in enumerate(parts)])
    field = np.concatenate([p[2]["f"] + 0.4 * k for k, p in enumerate(parts)])
    mesh = client.upload_mesh((points, tetrahedra, {"f": field}), name="three lattices")
    try:
        with client.open_session(mesh, structure="explicit") as session:
            for kind in KINDS:
                result = _run(session, kind, digests=True)
                tree = result.tree
                assert result.summary["components"] == 3 == len(tree.component_offsets) - 1
                assert tree.arcs_sha256() == result.summary["arcs_sha256"], kind
                assert tree.segmentation_sha256() == result.summary["segmentation_sha256"], kind
                wire = result.group("tree_arcs")
                np.testing.assert_array_equal(tree.arcs.component, wire["ComponentId"])
                assert (tree.arcs.down - wire["downNodeId"]
                        == tree.component_offsets[tree.arcs.component]).all()
                np.testing.assert_array_equal(
                    np.diff(tree.component_offsets),
                    np.bincount(result.group("tree_nodes")["ComponentId"], minlength=3))
                # Each component's vertices are on its own arcs.
                component = np.searchsorted(firsts, np.arange(len(points)), side="right") - 1
                np.testing.assert_array_equal(tree.arcs.component[tree.segmentation.arc],
                                              component)
                assert (~tree.branches().is_finite).sum() == 3
    finally:
        client.delete_mesh(mesh)


@pytest.fixture(scope="module")
def trees_ttk():
    if not TREES_TTK.is_file():
        pytest.skip(f"TTK's tree references not found ({TREES_TTK})")
    return json.loads(TREES_TTK.read_text())["results"]


def _check_ttk(tree: Tree, expected: dict) -> None:
    assert (len(tree.nodes), len(tree.arcs)) == (expected["nodes"], expected["arcs"])
    assert tree.counts_by_type() == expected["critical_types"]
    for name in ("nodes_sha256", "arcs_sha256", "segmentation_sha256"):
        assert getattr(tree, name)() == expected[name], name


def test_two_components_equal_ttks(client, data_dir, trees_ttk):
    """fertility twice, the copy moved and its field + 1000, as TTK's reference builds it: TTK's
    NodeIds go on across the two components, its upNodeId and downNodeId restart."""
    grid = meshio.read(data_dir / "fertility_tet.vtu")
    points = np.vstack([grid.points, grid.points + np.array([100.0, 0.0, 0.0])])
    tetrahedra = grid.cells_dict["tetra"]
    height = grid.point_data["height"]
    mesh = client.upload_mesh((points, np.vstack([tetrahedra, tetrahedra + len(grid.points)]),
                               {"height": np.concatenate([height, height + 1000])}),
                              name="fertility twice")
    try:
        with client.open_session(mesh, structure="compact") as session:
            for kind in KINDS:
                tree = _run(session, kind).tree
                assert tree.component_offsets[0] == 0 and len(tree.component_offsets) == 3
                _check_ttk(tree, trees_ttk["twice:fertility_tet.vtu"]["height"]["trees"][
                    f"{kind}_tree"])
    finally:
        client.delete_mesh(mesh)


@pytest.mark.parametrize("fraction", ["0.01", "0.05"])
def test_simplified_trees_equal_ttks(client, meshes, trees_ttk, fraction):
    """A threshold gives TTK's tree of the field that TopologicalSimplification leaves."""
    expected = trees_ttk["fertility_tet.vtu"]["height"]["simplified"][fraction]
    with client.open_session(meshes("fertility_tet.vtu"), scalar="height",
                             structure="compact") as session:
        for kind in KINDS:
            result = _run(session, kind, parameters={"relative_threshold": fraction})
            assert result.tree is not None and result.simplified is not None
            _check_ttk(result.tree, expected[f"{kind}_tree"])


def test_tree_is_none_without_a_tree(client, meshes):
    with client.open_session(meshes("manifoldCheck0_tet.vtu")) as session:
        assert session.run("morse-smale").tree is None
        summary_only = session.run("merge-tree", include_arrays=False)
        assert summary_only.tree is None and summary_only.summary["nodes"] == 4
        with pytest.raises(actopo.InvalidArgumentError, match=r"parameters\.tree"):
            session.run("merge-tree", parameters={"tree": "contour"})


def test_each_field_of_a_job_over_fields_has_its_tree(client, meshes):
    with client.open_session(meshes("fertility_tet.vtu"), structure="compact") as session:
        result = session.run("contour-tree", fields="all")
    for field in result.fields:
        expected = ttk("fertility_tet.vtu", field.field)["merge_trees"]["contour_tree"]
        assert field.tree is not None and field.tree.arcs_sha256() == expected["arcs_sha256"]


def test_files_equal_actopo_benchs(client, data_dir, tmp_path):
    if not BENCH_BIN.is_file():
        pytest.skip(f"actopo-bench not built ({BENCH_BIN}); set ACTOPO_BENCH_BIN")
    mesh = client.load_mesh("fertility_tet.vtu")
    try:
        with client.open_session(mesh, scalar="height", structure="compact") as session:
            result = _run(session, "contour")
        files = result.write(str(tmp_path / "client"), data_dir / "fertility_tet.vtu")
    finally:
        client.delete_mesh(mesh)
    names = ["tree_nodes.vtp", "tree_arcs.vtp", "segmentation.vtu"]
    assert [Path(f).name for f in files] == [f"client_{n}" for n in names]
    subprocess.run([str(BENCH_BIN), "--mesh", str(data_dir / "fertility_tet.vtu"), "--scalar",
                    "height", "--algorithm", "contour-tree", "--output", str(tmp_path / "bench")],
                   capture_output=True, timeout=120, check=True)
    for name in names:
        ours, theirs = pv.read(tmp_path / f"client_{name}"), pv.read(tmp_path / f"bench_{name}")
        np.testing.assert_array_equal(ours.points, theirs.points)
        if name.endswith(".vtp"):
            np.testing.assert_array_equal(ours.lines, theirs.lines)
            np.testing.assert_array_equal(ours.verts, theirs.verts)
        for data, other in ((ours.point_data, theirs.point_data),
                            (ours.cell_data, theirs.cell_data)):
            assert sorted(data.keys()) == sorted(other.keys()), name
            for key in other.keys():  # noqa: SIM118 (pyvista)
                if key != "height":  # the file's own field, float32 here, float64 there
                    np.testing.assert_array_equal(data[key], other[key], err_msg=key)


def test_files_with_meshio_only(sample, tmp_path, monkeypatch):
    result = sample[0]["split"]
    monkeypatch.setitem(sys.modules, "pyvista", None)  # as if pyvista were not installed
    nodes, arcs = (meshio.read(path) for path in result.write(str(tmp_path / "split")))
    tree = result.tree
    assert nodes.cells[0].type == "vertex" and len(nodes.points) == len(tree.nodes)
    np.testing.assert_array_equal(nodes.point_data["VertexId"], tree.nodes.vertex)
    assert arcs.cells[0].type == "line" and len(arcs.cells[0].data) == len(tree.arcs)
    np.testing.assert_array_equal(arcs.points[arcs.cells[0].data[:, 1]],
                                  tree.nodes.points[tree.arcs.down])  # the upper end
    np.testing.assert_array_equal(arcs.cell_data["upNodeId"][0], tree.arcs.up)
    assert len(arcs.point_data["Scalar"]) == len(arcs.points)


def test_plot_of_a_sample_tree(sample, tmp_path):
    for kind, result in sample[0].items():
        tree = result.tree
        ax = tree.plot()
        labels = [t.get_text() for t in ax.texts]
        assert len(labels) == min(20, len(tree.branches())), kind
        assert labels[0].endswith(" (inf)")  # the most persistent: the whole range
        heights = np.concatenate([c.get_offsets()[:, 1] for c in ax.collections[1:]])
        assert sorted(heights.tolist()) == sorted(tree.nodes.scalar.astype(float).tolist())
        path = tree.save_plot(tmp_path / f"{kind}.png", annotate=5)
        assert matplotlib.image.imread(path).shape[0] == 900  # 6 in at 150 dpi


# The command line.


def test_cli_plot_writes_a_png(cli, tmp_path):
    path = tmp_path / "trees" / "join.png"
    status, out, err = cli("run", "merge-tree", "--sample", SAMPLE, "--plot", str(path),
                           "--json", "--digests")
    assert status == 0, err
    report = json.loads(out)
    assert report["plot"] == str(path) and report["algorithm"] == "merge-tree"
    assert report["result"]["tree"] == "join" and report["result"]["nodes"] == 90
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    pixels = matplotlib.image.imread(path)
    assert pixels.shape[0] == 900 and pixels[..., :3].std() > 0
    status, out, err = cli("run", "merge-tree", "--sample", SAMPLE, "--tree", "split",
                           "--plot", str(tmp_path / "split.png"))
    assert status == 0, err
    assert '"tree": "split"' in out and f"wrote {tmp_path / 'split.png'}" in out
    status, out, err = cli("run", "--algorithm", "contour-tree", "--sample", SAMPLE, "--param",
                           "relative_threshold=0.05", "--plot", str(tmp_path / "ct.png"),
                           "--json")
    assert status == 0, err
    report = json.loads(out)
    assert report["result"]["tree"] == "contour" and "simplification" in report["result"]
    assert (tmp_path / "ct.png").stat().st_size > 0


def test_cli_tree_parameter_and_usage(cli, capsys, tmp_path):
    status, out, err = cli("run", "merge-tree", "--sample", SAMPLE, "--tree", "split", "--json")
    assert status == 0, err
    report = json.loads(out)
    assert report["config"]["parameters"] == {"tree": "split"}
    assert report["result"]["tree"] == "split" and report["result"]["nodes"] == 10
    status, _, err = cli("run", "merge-tree", "--sample", SAMPLE, "--param", "tree=contour")
    assert status == 1 and "parameters.tree: unknown value 'contour'" in err
    plot = ("--plot", str(tmp_path / "x.png"))
    status, out, err = cli("run", "merge-tree", "--sample", SAMPLE, *plot, "--threshold", "1%")
    assert status == 2 and out == ""
    assert "--threshold draws on a persistence diagram; merge-tree takes --param" in err
    status, _, err = cli("run", "contour-tree", "--mesh-id", "mesh-never-asked", "--scalars",
                         "a,b", *plot)
    assert status == 2 and "--plot draws one field's tree" in err
    status, _, err = cli("run", "critical-points", "--mesh-id", "mesh-never-asked", *plot)
    assert status == 2 and "run persistence-diagram, merge-tree or contour-tree" in err
    assert not (tmp_path / "x.png").exists()
    with pytest.raises(SystemExit) as usage:
        cli("run", "merge-tree", "--sample", SAMPLE, "--tree", "contour")
    assert usage.value.code == 2
    assert "--tree: invalid choice: 'contour'" in capsys.readouterr().err
