"""The names the API takes for the proto's enums, as Literal types to annotate with.

They list the spellings the package documents (relations with '_', algorithms with '-'). At run
time the client also accepts either separator and any case, and rejects any other name with an
InvalidArgumentError that names the parameter (see _names.lookup). The values equal the proto
enums' names the package maps; a test keeps the two in step.
"""

from __future__ import annotations

from typing import Literal, TypeAlias

Structure: TypeAlias = Literal["explicit", "compact", "actopo"]
"""A topological data structure: the explicit one, the compact one, or the actopo engine."""

Algorithm: TypeAlias = Literal["topo-relations", "critical-points", "discrete-gradient",
                               "morse-smale", "persistence-diagram",
                               "topological-simplification", "diagram-distance", "tracking",
                               "merge-tree", "contour-tree"]
"""An algorithm that Session.run() runs; "diagram-distance" and "tracking" run over several
fields (its ``fields`` argument; Session.distance_matrix() runs the first); "merge-tree" and
"contour-tree" give TTK's trees (JobResult.tree)."""

Relation: TypeAlias = Literal[
    "vertex_neighbors", "vertex_edges", "vertex_triangles", "vertex_star",
    "edge_vertices", "edge_triangles", "edge_star",
    "triangle_vertices", "triangle_edges", "triangle_star",
    "tetrahedron_vertices", "tetrahedron_edges", "tetrahedron_triangles",
    "tetrahedron_neighbors",
    "vertex_link", "edge_link", "triangle_link",
    "vertex_on_boundary", "edge_on_boundary", "triangle_on_boundary",
    "edge_neighbors", "triangle_neighbors",
]
"""A relation that Session.relation(), query() and their streaming forms ask."""

Prefetch: TypeAlias = Literal["auto", "linear", "spatial", "adaptive"]
"""Which blocks the actopo engine's producers compute ahead; "auto": chosen per algorithm."""

Precompute: TypeAlias = Literal["auto", "requested", "declared"]
"""Which relations the actopo engine's producers compute for a block; "auto": chosen per
algorithm."""
