"""Upstream TTK's results, and what the tests compute here to compare with them.

The references: shared/data/expected-ttk.json (critical points, discrete gradient, Morse-Smale
complex and persistence diagram of six (file, field) cases, ``upstream`` entries) and the
repository's tests/ttk_reference/simplification-ttk.json. Their digest formats are in
shared/data/README.md. A job's result is checked against them from the arrays the client
received, digested here, not only from the summary the server computed: the summary and
actopo-bench share the same C++ code, TTK does not.

Where TTK has no reference (the relation totals of topo-relations, the critical points with
boundary_rule "none"), small oracles below compute the answer from the mesh file in numpy.
"""

from __future__ import annotations

import functools
import hashlib
import itertools
import json
from collections.abc import Iterable
from typing import Any

import numpy as np
from harness import DATA_DIR, REPO

import actopo

EXPECTED_TTK = DATA_DIR / "expected-ttk.json"
SIMPLIFICATION_TTK = REPO / "tests" / "ttk_reference" / "simplification-ttk.json"
# The (file, field) cases of expected-ttk.json, listed so that the tests exist without reading
# it; test_jobs.py's test_every_expected_case_is_tested keeps the two equal.
CASES = [
    ("manifoldCheck0_tet.vtu", "height"),
    ("manifoldCheck1_tet.vtu", "height"),
    ("manifoldCheck2_tet.vtu", "height"),
    ("fertility_tet.vtu", "eigenfunction4"),
    ("fertility_tet.vtu", "height"),
    ("viscousFingers001_s2_tet.vtu", "density"),
]
CASE_IDS = [f"{f[:-8]}-{v}" for f, v in CASES]
CRITICAL_TYPES = ("minimum", "saddle1", "saddle2", "maximum", "degenerate")


@functools.cache
def _expected() -> dict[str, Any]:
    return json.loads(EXPECTED_TTK.read_text())


def expected_cases() -> list[tuple[str, str]]:
    return [(file, field) for file, fields in _expected().items() for field in fields]


def ttk(file: str, field: str) -> dict[str, Any]:
    """Upstream TTK's results on (file, field): mesh, critical_points, discrete_gradient,
    morse_smale, persistence_diagram."""
    entry: dict[str, Any] = _expected()[file][field]["upstream"]
    return entry


@functools.cache
def _simplification() -> dict[str, Any]:
    results: dict[str, Any] = json.loads(SIMPLIFICATION_TTK.read_text())["results"]
    return results


def ttk_simplification(file: str, field: str, threshold: str) -> dict[str, Any]:
    """TTK's topological simplification of (file, field) at relative `threshold` ("0.05")."""
    entry: dict[str, Any] = _simplification()[file][field][threshold]
    return entry


def sha256_lines(lines: Iterable[str]) -> str:
    return hashlib.sha256("".join(lines).encode()).hexdigest()


# Digests of the streamed arrays, in the references' formats.


def critical_points_sha256(points: dict[str, np.ndarray]) -> str:
    """"<vertex id> <type>" per critical vertex, in ascending id."""
    vertices, types = points["ttkVertexScalarField"], points["CriticalType"]
    order = np.argsort(vertices, kind="stable")
    return sha256_lines(f"{v} {t}\n" for v, t in zip(vertices[order].tolist(),
                                                        types[order].tolist(), strict=True))


_CELL_VERTICES = {1: "edge_vertices", 2: "triangle_vertices", 3: "tetrahedron_vertices"}


def critical_cells_sha256(cells: dict[str, np.ndarray], session: actopo.Session) -> str:
    """"<d> <cell>" per critical cell, the cell as its ascending vertex ids joined by ",", in
    byte order. The cells come as (CellDimension, CellId); the vertices of edges, triangles and
    tetrahedra are asked from the session that ran the job."""
    dimensions, ids = cells["CellDimension"], cells["CellId"]
    lines = [f"0 {v}\n" for v in ids[dimensions == 0].tolist()]
    for d, relation in _CELL_VERTICES.items():
        of_d = ids[dimensions == d]
        if len(of_d):
            for vertices in session.relation(relation, of_d).split():
                lines.append(f"{d} {','.join(map(str, sorted(vertices.tolist())))}\n")
    return sha256_lines(sorted(lines, key=str.encode))


def segmentation_sha256(labels: np.ndarray) -> str:
    """"<vertex id> <label>" for every vertex, in ascending id."""
    return sha256_lines(f"{v} {label}\n" for v, label in enumerate(labels.tolist()))


# A job's result against TTK's.


def check_critical_points(result: actopo.JobResult, expected: dict[str, Any], *,
                          digests: bool = False) -> None:
    points = result.critical_points
    counts = np.bincount(points["CriticalType"], minlength=5).tolist()
    assert dict(zip(CRITICAL_TYPES, counts, strict=True)) == expected["counts"]
    assert critical_points_sha256(points) == expected["vertices_sha256"]
    check_summary("critical-points", result.summary, expected, digests=digests)


def check_discrete_gradient(result: actopo.JobResult, session: actopo.Session,
                            expected: dict[str, Any]) -> None:
    """The critical cells from the arrays; the gradient pairs are not streamed, so their
    digest and counts are the summary's: the job must have asked for digests."""
    cells = result.critical_cells
    counts = np.bincount(cells["CellDimension"], minlength=4).tolist()
    assert counts == expected["critical_cells"]
    assert critical_cells_sha256(cells, session) == expected["critical_cells_sha256"]
    check_summary("discrete-gradient", result.summary, expected, digests=True)


_SEGMENTATION = {"descending": "DescendingManifold", "ascending": "AscendingManifold",
                 "morse_smale": "MorseSmaleManifold"}


def check_morse_smale(result: actopo.JobResult, session: actopo.Session,
                      expected: dict[str, Any], gradient: dict[str, Any] | None = None, *,
                      digests: bool = False) -> None:
    """Counts, regions and segmentation digests from the arrays; the critical cells' digest
    against TTK's gradient (`gradient`, the same field's discrete_gradient entry) when given."""
    points, separatrices = result.critical_points, result.separatrices
    dimensions = points["CellDimension"]
    assert np.bincount(dimensions, minlength=4).tolist() == expected["critical_cells"]
    # No separatrices, no arrays: the group is absent then.
    types = separatrices.get("SeparatrixType", np.zeros(0, dtype=np.int8))
    kinds = np.bincount(types, minlength=3).tolist()
    segments = len(separatrices.get("Points", [])) - len(types)  # a polyline per separatrix
    assert {"descending": kinds[0], "saddle_connectors": kinds[1], "ascending": kinds[2],
            "segments": segments} == expected["separatrices"]
    sizes = points["ManifoldSize"]
    assert {"minima": int(sizes[dimensions == 0].sum()),
            "maxima": int(sizes[dimensions == 3].sum())} == expected["manifold_size_sum"]
    for key, name in _SEGMENTATION.items():
        labels = result.segmentation[name]
        assert segmentation_sha256(labels) == expected["segmentation_sha256"][key], name
        assert len(np.unique(labels)) == expected["regions"][key], name
        assert int((labels == -1).sum()) == expected["unlabelled_vertices"][key], name
    if gradient is not None:
        assert critical_cells_sha256(points, session) == gradient["critical_cells_sha256"]
    check_summary("morse-smale", result.summary, expected, digests=digests)


# What each summary holds of TTK's entry (the summary's own keys).
_SUMMARY_KEYS = {
    "critical-points": ("counts", "vertices_sha256"),
    "discrete-gradient": ("critical_cells", "critical_cells_sha256", "pairs_count",
                          "pairs_sha256"),
    "morse-smale": ("critical_cells", "separatrices", "regions", "manifold_size_sum",
                    "unlabelled_vertices", "segmentation_sha256"),
    "persistence-diagram": ("pairs", "counts_by_type", "max_persistence", "pairs_sha256"),
    "topological-simplification": ("threshold", "kept_pairs", "changed_values",
                                   "scalars_sha256", "order_sha256"),
}
ENTRY = {"critical-points": "critical_points", "discrete-gradient": "discrete_gradient",
         "morse-smale": "morse_smale", "persistence-diagram": "persistence_diagram"}


def check_summary(algorithm: str, summary: dict[str, Any], expected: dict[str, Any], *,
                  digests: bool) -> None:
    """The summary's counts equal TTK's (`expected`: the algorithm's entry), and so do its
    digests when the job asked for them (`digests`); a job that did not has none."""
    for key in _SUMMARY_KEYS[algorithm]:
        if key.endswith("_sha256") and not digests:
            assert key not in summary, f"{algorithm} {key} sent unasked"
        else:
            assert summary[key] == expected[key], f"{algorithm} {key}"


# Oracles from the mesh file, where TTK has no reference.


def _faces(tets: np.ndarray, k: int) -> np.ndarray:
    """Every k-vertex face of every tetrahedron, vertices ascending (with repeats)."""
    corners = np.sort(tets, axis=1)
    return np.concatenate([corners[:, list(c)] for c in itertools.combinations(range(4), k)])


def relation_totals(tets: np.ndarray) -> dict[str, int]:
    """topo-relations' relation_totals (the lengths of every relation over all its simplices,
    one value per simplex for the boundary predicates), counted from the tetrahedra."""
    t = len(tets)
    vertices = len(np.unique(tets))
    edges = np.unique(_faces(tets, 2), axis=0)
    triangles, triangle_tets = np.unique(_faces(tets, 3), axis=0, return_counts=True)
    e, f = len(edges), len(triangles)
    degree = np.bincount(edges.ravel(), minlength=vertices)  # edges per vertex
    edges_of_triangles = np.unique(
        np.concatenate([triangles[:, [0, 1]], triangles[:, [0, 2]], triangles[:, [1, 2]]]),
        axis=0, return_counts=True)[1]  # triangles per edge
    return {
        "vertex_neighbors": 2 * e, "vertex_edges": 2 * e, "vertex_triangles": 3 * f,
        "vertex_star": 4 * t, "edge_vertices": 2 * e, "edge_triangles": 3 * f,
        "edge_star": 6 * t, "triangle_vertices": 3 * f, "triangle_edges": 3 * f,
        "triangle_star": 4 * t, "tetrahedron_vertices": 4 * t, "tetrahedron_edges": 6 * t,
        "tetrahedron_triangles": 4 * t,
        "tetrahedron_neighbors": 2 * int((triangle_tets == 2).sum()),
        # A link has one simplex per tetrahedron of the star: the face opposite.
        "vertex_link": 4 * t, "edge_link": 6 * t, "triangle_link": 4 * t,
        "vertex_on_boundary": vertices, "edge_on_boundary": e, "triangle_on_boundary": f,
        # The edges sharing a vertex with an edge, the triangles sharing an edge with a triangle.
        "edge_neighbors": int((degree.astype(np.int64) ** 2).sum()) - 2 * e,
        "triangle_neighbors": int((edges_of_triangles * (edges_of_triangles - 1)).sum()),
    }


def critical_points(tets: np.ndarray, scalars: np.ndarray,
                    boundary_rule: str = "ttk") -> list[tuple[int, int]]:
    """(vertex, TTK type) of every critical vertex, in ascending id, by the definition in
    server/algorithms/critical_points.h: the components of the lower and upper link (two link
    vertices connect when they are two other vertices of a tetrahedron of the star, on the same
    side), ties of the field broken by vertex id; with the "ttk" boundary rule a (1, 1) boundary
    vertex is a 1-saddle when an upper neighbour is on the boundary and no lower one is, a
    2-saddle in the reverse case."""
    n = len(scalars)
    rank = np.empty(n, dtype=np.int64)
    rank[np.lexsort((np.arange(n), scalars))] = np.arange(n)
    # Link incidences (v, a), one node each, and the link edges (v: a-b) on one side of v.
    centers, ends, others = [], [], []
    for i in range(4):
        rest = [j for j in range(4) if j != i]
        for a, b in itertools.permutations(rest, 2):
            centers.append(tets[:, i])
            ends.append(tets[:, a])
            others.append(tets[:, b])
    v, a, b = (np.concatenate(x).astype(np.int64) for x in (centers, ends, others))
    keys, node = np.unique(v * n + a, return_inverse=True)
    other = np.searchsorted(keys, v * n + b)
    same_side = (rank[a] < rank[v]) == (rank[b] < rank[v])
    u, w = node[same_side], other[same_side]
    labels = np.arange(len(keys))
    while True:  # connected components: the smallest node id of each, by propagation
        merged = labels.copy()
        np.minimum.at(merged, u, labels[w])
        np.minimum.at(merged, w, labels[u])
        merged = merged[merged]
        if np.array_equal(merged, labels):
            break
        labels = merged
    center, end = keys // n, keys % n
    lower = rank[end] < rank[center]
    components = np.unique(np.stack([center, lower, labels], axis=1), axis=0)
    lower_count = np.bincount(components[components[:, 1] == 1, 0], minlength=n)
    upper_count = np.bincount(components[components[:, 1] == 0, 0], minlength=n)
    triangles, count = np.unique(_faces(tets, 3), axis=0, return_counts=True)
    boundary = np.zeros(n, dtype=bool)
    boundary[triangles[count == 1].ravel()] = True
    on_boundary = boundary[end]
    lower_on_boundary = np.bincount(center[lower & on_boundary], minlength=n) > 0
    upper_on_boundary = np.bincount(center[~lower & on_boundary], minlength=n) > 0
    found = []
    for vertex in range(n):
        kind = {(0, 1): 0, (1, 0): 3, (2, 1): 1, (1, 2): 2, (1, 1): None}.get(
            (int(lower_count[vertex]), int(upper_count[vertex])), 4)
        if kind is None and boundary_rule == "ttk" and boundary[vertex]:
            if upper_on_boundary[vertex] and not lower_on_boundary[vertex]:
                kind = 1
            elif lower_on_boundary[vertex] and not upper_on_boundary[vertex]:
                kind = 2
        if kind is not None:
            found.append((vertex, kind))
    return found
