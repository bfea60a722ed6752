"""Merge trees and contour trees: the ``tree_nodes/``, ``tree_arcs/`` and ``segmentation/``
arrays of a merge-tree or contour-tree job as one typed object, with the arcs' ends as global
NodeIds, the digests of the summary, the branches and their persistence, a networkx graph and
a plot.

The server streams TTK's three outputs (see the proto's ResultChunk): a point per node (NodeId,
Scalar, VertexId, CriticalType, RegionSize, RegionSpan), a line per arc from its lower node's
point to its upper node's (SegmentationId, upNodeId, downNodeId, RegionSize, RegionSpan), and
per vertex the SegmentationId of the arc it lies on, with that arc's RegionSize, RegionSpan and
RegionType.

Global NodeIds. TTK builds one tree per connected component of the mesh. NodeId counts on
across the components, but upNodeId and downNodeId restart at 0 in each (they are relative to
the component's first NodeId). The server streams beside TTK's arrays a ComponentId of its own
per node (tree_nodes/ComponentId: 0, 1, ..., each component a run of NodeIds) and per arc
(tree_arcs/ComponentId), so an arc's global ids are its local ids plus the first NodeId whose
ComponentId is the arc's. from_arrays() checks that the node ComponentIds run 0, 1, ... over
NodeId and that each local id falls within its component's nodes.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal, TypeAlias, cast, get_args

import numpy as np

from actopo import _plot
from actopo._errors import ActopoError

if TYPE_CHECKING:
    from matplotlib.axes import Axes

TreeKind: TypeAlias = Literal["join", "split", "contour"]
"""The tree of a merge-tree job ("join", the default, or "split" with its parameter "tree") or
of a contour-tree job ("contour"), as the summary's "tree" names it."""

CRITICAL_TYPES = {0: "minimum", 1: "1-saddle", 2: "2-saddle", 3: "maximum", 4: "degenerate",
                  5: "regular"}
"""TTK's CriticalType of a tree node. A join tree's leaves are minima and its root a maximum,
a split tree's the reverse; 4 is a merge of three or more, or a saddle that is also a root; 5 a
one-vertex component."""

_LINES_PER_UPDATE = 1 << 16
"""Lines formatted at a time into a digest, so that the text is never held whole."""


@dataclass(frozen=True, eq=False)
class TreeNodes:
    """A tree's nodes, one entry per node in NodeId order (TTK's tree_nodes output).

    Attributes:
        node_id: TTK's NodeId (int32): 0, 1, 2, ...
        vertex: the node's vertex (int32 input id; TTK's VertexId).
        scalar: its value (float32, TTK's Scalar: the field cast to float; the simplified field
            with a threshold).
        critical_type: TTK's CriticalType (int32), see CRITICAL_TYPES.
        region_size, region_span: the RegionSize and RegionSpan of one of the node's arcs
            (int32; TTK truncates the span).
        points: the vertex's position, (n, 3) float64.
    """

    node_id: np.ndarray
    vertex: np.ndarray
    scalar: np.ndarray
    critical_type: np.ndarray
    region_size: np.ndarray
    region_span: np.ndarray
    points: np.ndarray

    def __len__(self) -> int:
        return len(self.node_id)


@dataclass(frozen=True, eq=False)
class TreeArcs:
    """A tree's arcs in TTK's cell order (TTK's tree_arcs output, one entry per line).

    Attributes:
        down, up: the arc's nodes as global NodeIds (int32), in the tree's sense: down is the
            leaf side. The join and contour trees' down node is the lower one, the split tree's
            the higher one. TTK's downNodeId and upNodeId are these minus their component's
            first NodeId (component_offsets); a root's self-loop has down == up.
        segmentation_id: TTK's SegmentationId (int32), the arc's id in ``segmentation``.
        region_size: the vertices inside the arc, its nodes left out (int32).
        region_span: the distance between its nodes' vertices (float64, computed in float).
        component: the connected component of the mesh the arc lies in (int32; the
            server's tree_arcs/ComponentId).
    """

    down: np.ndarray
    up: np.ndarray
    segmentation_id: np.ndarray
    region_size: np.ndarray
    region_span: np.ndarray
    component: np.ndarray

    def __len__(self) -> int:
        return len(self.down)


@dataclass(frozen=True, eq=False)
class TreeSegmentation:
    """Per vertex in input ids, the arc it lies on (TTK's segmentation output). A node's vertex
    lies on the last arc in cell order that touches the node.

    Attributes:
        segmentation_id: the arc's SegmentationId (int32).
        arc: the arc's index in ``Tree.arcs`` (int32).
        region_size, region_span, region_type: the arc's RegionSize (int32), RegionSpan
            (float64) and RegionType (int8: 0 an end is a minimum, else 1 an end is a maximum,
            else 2 both ends 1-saddles, 3 both 2-saddles, 4 otherwise).
    """

    segmentation_id: np.ndarray
    arc: np.ndarray
    region_size: np.ndarray
    region_span: np.ndarray
    region_type: np.ndarray

    def __len__(self) -> int:
        return len(self.arc)


@dataclass(frozen=True, eq=False)
class TreeBranches:
    """A tree's branches by the elder rule, most persistent first. A branch runs from a leaf
    to the node where its sublevel component (superlevel, for a split tree's maxima) merges
    into an older one: the younger, whose leaf is higher (lower), ends there.

    Attributes:
        leaf: the branch's leaf, a NodeId (int32): a minimum of a join tree, a maximum of a
            split tree, either of a contour tree.
        end: where it ends, a NodeId (int32): the saddle of the merge, or for an infinite
            branch the other end of its component (the root of a merge tree; a contour tree's
            global maximum).
        persistence: |value(end) - value(leaf)| of the nodes' float32 scalars (float64).
        is_finite: False for the one branch per connected component that never merges (bool).
    """

    leaf: np.ndarray
    end: np.ndarray
    persistence: np.ndarray
    is_finite: np.ndarray

    def __len__(self) -> int:
        return len(self.leaf)


@dataclass(frozen=True, eq=False)
class Tree:
    """The join, split or contour tree of a merge-tree or contour-tree job (TTK's MergeTree and
    ContourTree outputs), as numpy arrays.

    Attributes:
        kind: "join", "split" or "contour".
        nodes: TreeNodes, by NodeId.
        arcs: TreeArcs, with global NodeIds.
        segmentation: TreeSegmentation, per vertex.
        component_offsets: (k + 1,) int64: the NodeIds of connected component i are
            component_offsets[i] to component_offsets[i + 1] - 1 (from the server's
            tree_nodes/ComponentId).

    Example::

        tree = session.run("merge-tree", parameters={"tree": "split"}).tree
        print(tree, tree.counts_by_type())
        branches = tree.branches()                     # most persistent first
        print(tree.nodes.vertex[branches.leaf[:5]], branches.persistence[:5])
        graph = tree.to_networkx()                     # needs networkx
        tree.save_plot("split.png")                    # needs matplotlib
    """

    kind: TreeKind
    nodes: TreeNodes
    arcs: TreeArcs
    segmentation: TreeSegmentation
    component_offsets: np.ndarray

    def __repr__(self) -> str:
        components = len(self.component_offsets) - 1
        return (f"Tree({self.kind!r}, {len(self.nodes)} nodes, {len(self.arcs)} arcs, "
                f"{components} component{'s' if components != 1 else ''})")

    def counts_by_type(self) -> dict[str, int]:
        """Nodes per CriticalType as the summary's ``critical_types`` counts them: {"0": n,
        ...}, the types without nodes left out."""
        kinds, counts = np.unique(self.nodes.critical_type, return_counts=True)
        return {str(k): int(c) for k, c in zip(kinds.tolist(), counts.tolist(), strict=True)}

    def _ends(self) -> tuple[np.ndarray, np.ndarray]:
        """Each arc's down and up node as input vertex ids."""
        return self.nodes.vertex[self.arcs.down], self.nodes.vertex[self.arcs.up]

    def nodes_sha256(self) -> str:
        """The SHA-256 of "<vertex> <CriticalType>\\n" per node, by ascending vertex: the
        summary's ``nodes_sha256`` (with digests=True) and TTK's, computed here."""
        order = np.argsort(self.nodes.vertex, kind="stable")
        return _sha256(zip(self.nodes.vertex[order].tolist(),
                           self.nodes.critical_type[order].tolist(), strict=True))

    def arcs_sha256(self) -> str:
        """The SHA-256 of "<down vertex> <up vertex>\\n" per arc (tree sense), sorted as integer
        pairs: the summary's ``arcs_sha256`` and TTK's, computed here from global NodeIds."""
        down, up = self._ends()
        order = np.lexsort((up, down))
        return _sha256(zip(down[order].tolist(), up[order].tolist(), strict=True))

    def segmentation_sha256(self) -> str:
        """The SHA-256 of "<v> <down vertex> <up vertex>\\n" for every vertex v ascending, the
        tree-sense ends of the arc v lies on: the summary's ``segmentation_sha256`` and
        TTK's."""
        down, up = self._ends()
        arc = self.segmentation.arc
        return _sha256(zip(range(len(arc)), down[arc].tolist(), up[arc].tolist(), strict=True))

    def branches(self) -> TreeBranches:
        """The branches by the elder rule: at each merge of components of sublevel sets (of
        superlevel sets for the split tree), the one born at the older leaf goes on and the
        others end. A join tree's finite branches are the persistence diagram's finite
        minimum - 1-saddle pairs, and on a mesh of one component its infinite branch is the
        diagram's infinite pair (TTK ends every infinite pair at the global maximum, a branch
        at its component's root). A split tree pairs the maxima the same way, from the top. A
        contour tree gives the branches of both sweeps, and its infinite ones (each
        component's minimum to its maximum) once.

        Ages are exact for merge trees (TTK's NodeIds follow the vertex order). A contour
        tree's are by (float32 value, vertex id), which may differ from the field's order
        only where two values differ by less than float32 can tell."""
        order = self._rank_order()
        adjacency = self._adjacency()
        leaf, end, finite, _ = _elder_rule(order, *adjacency)
        if self.kind == "contour":  # the maxima's branches: the sweep from the top
            top_leaf, top_end, top_finite, _ = _elder_rule(order[::-1], *adjacency)
            leaf = np.concatenate([leaf, top_leaf[top_finite]])
            end = np.concatenate([end, top_end[top_finite]])
            finite = np.concatenate([finite, top_finite[top_finite]])
        scalar = self.nodes.scalar.astype(np.float64)
        persistence = np.abs(scalar[end] - scalar[leaf])
        index = np.lexsort((leaf, -persistence))
        return TreeBranches(leaf[index].astype(np.int32), end[index].astype(np.int32),
                            persistence[index], finite[index])

    def largest_regions(self, k: int) -> np.ndarray:
        """The indices of the k arcs with the most vertices inside (RegionSize), largest first,
        ties by index (int64): ``tree.arcs.down[i]``, ``tree.region_vertices(i)``, ..."""
        order = np.lexsort((np.arange(len(self.arcs)), -self.arcs.region_size.astype(np.int64)))
        return order[:max(int(k), 0)]

    def region_vertices(self, arc: int) -> np.ndarray:
        """The vertices (input ids, ascending) that the segmentation puts on arc `arc`, an index
        in ``arcs``: its RegionSize inner vertices and the node vertices given to it."""
        return np.flatnonzero(self.segmentation.arc == arc)

    def to_networkx(self, self_loops: bool = False) -> Any:
        """The tree as a networkx DiGraph (needs networkx): a node per NodeId with the
        attributes vertex, scalar, critical_type, region_size, region_span and position (x, y,
        z); an edge per arc from its down node to its up node (towards the root of a merge
        tree, upwards in a contour tree) with arc (its index), segmentation_id, region_size and
        region_span. A root's self-loop arc is left out unless `self_loops`, so that each
        connected component is a tree (networkx.is_tree on one component)."""
        try:
            import networkx
        except ImportError:
            raise ImportError("Tree.to_networkx() needs networkx: pip install networkx (or "
                              "pip install 'actopo[networkx]')") from None
        graph = networkx.DiGraph(kind=self.kind)
        n = self.nodes
        graph.add_nodes_from(
            (i, {"vertex": v, "scalar": s, "critical_type": t, "region_size": rs,
                 "region_span": sp, "position": tuple(p)})
            for i, v, s, t, rs, sp, p in zip(
                n.node_id.tolist(), n.vertex.tolist(), n.scalar.tolist(),
                n.critical_type.tolist(), n.region_size.tolist(), n.region_span.tolist(),
                n.points.tolist(), strict=True))
        a = self.arcs
        graph.add_edges_from(
            (d, u, {"arc": i, "segmentation_id": sid, "region_size": rs, "region_span": sp})
            for i, (d, u, sid, rs, sp) in enumerate(zip(
                a.down.tolist(), a.up.tolist(), a.segmentation_id.tolist(),
                a.region_size.tolist(), a.region_span.tolist(), strict=True))
            if self_loops or d != u)
        return graph

    def plot(self, ax: Axes | None = None, *, annotate: int = 20,
             title: str | None = None) -> Axes:
        """Draws the tree with matplotlib (the ``plot`` extra): each node at its value on the
        y axis, coloured by CriticalType, the arcs as segments, the leaves spread on x. A merge
        tree is drawn by branches: each branch a vertical line from its leaf, joined to the
        saddle where it ends by an elbow at the saddle's value, so that its height is its
        persistence. A contour tree hangs from its global maximum, each inner node midway
        between its children. The `annotate` most persistent branches have their persistence
        written beside their leaf (an infinite one with "(inf)"). Into `ax`, else a new Figure
        (no pyplot); returns the axes."""
        return _plot.draw_tree(*self._drawing(annotate), elbows=self.kind != "contour",
                               title=self._title(title), ax=ax)

    def save_plot(self, path: str | os.PathLike[str], *, annotate: int = 20,
                  title: str | None = None) -> str:
        """plot() into a file (PNG, SVG, PDF, ... by the suffix); returns the path."""
        return _plot.save_tree(path, *self._drawing(annotate), elbows=self.kind != "contour",
                               title=self._title(title))

    def _title(self, title: str | None) -> str:
        if title is not None:
            return title
        return f"{self.kind} tree: {len(self.nodes)} nodes, {len(self.arcs)} arcs"

    # The elder rule and the drawing's layout.

    def _rank_order(self) -> np.ndarray:
        """The NodeIds from the oldest leaf's side: ascending NodeId for a merge tree (TTK's
        numbering follows the sweep within each component), by (value, vertex) for a contour
        tree."""
        if self.kind != "contour":
            return np.arange(len(self.nodes))
        return np.lexsort((self.nodes.vertex, self.nodes.scalar))

    def _adjacency(self) -> tuple[np.ndarray, np.ndarray]:
        """The neighbours of each node over the arcs, self-loops left out, as CSR (indptr,
        indices)."""
        keep = self.arcs.down != self.arcs.up
        ends = np.concatenate([self.arcs.down[keep], self.arcs.up[keep]]).astype(np.int64)
        others = np.concatenate([self.arcs.up[keep], self.arcs.down[keep]]).astype(np.int64)
        order = np.argsort(ends, kind="stable")
        counts = np.bincount(ends, minlength=len(self.nodes))
        return np.concatenate([[0], np.cumsum(counts)]), others[order]

    def _layout(self) -> tuple[np.ndarray, np.ndarray]:
        """Each node's x and its parent towards its component's root (-1 at a root). The
        leaves are numbered depth-first from each root, the subtree of the oldest branch first.
        A merge tree's node sits on its branch's leaf (the elder rule's), so each branch is a
        vertical line; a contour tree, rooted at its global maximum, has each inner node at
        the mean of its children."""
        indptr, indices = self._adjacency()
        order = self._rank_order()
        _, end, finite, on_branch = _elder_rule(order, indptr, indices)
        age = np.empty(len(self.nodes), dtype=np.int64)
        age[order] = np.arange(len(self.nodes))
        x = np.zeros(len(self.nodes))
        parent = np.full(len(self.nodes), -1, dtype=np.int64)
        leaves = 0
        for root in end[~finite].tolist():
            children = _children(root, indptr, indices)
            nodes = list(_depth_first(root, children, lambda c: age[on_branch[c]]))
            for node in nodes:
                parent[children[node]] = node
                if not children[node]:
                    x[node] = leaves
                    leaves += 1
            if self.kind != "contour":
                x[nodes] = x[on_branch[nodes]]
                continue
            for node in reversed(nodes):  # children before their parent
                if children[node]:
                    x[node] = np.mean(x[children[node]])
        return x, parent

    def _drawing(self, annotate: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                                list[tuple[int, int, str]]]:
        """What _plot.draw_tree takes: x and y per node, the arcs as (child, parent) rows
        without self-loops, the types, and the labels (leaf, end, text) of the most persistent
        branches."""
        x, parent = self._layout()
        keep = self.arcs.down != self.arcs.up
        down, up = self.arcs.down[keep], self.arcs.up[keep]
        child = np.where(parent[down] == up, down, up)
        segments = np.stack([child, parent[child]], axis=1)
        b = self.branches()
        shown = slice(0, max(annotate, 0))
        labels = [(leaf, end, f"{p:.3g}" + ("" if finite else " (inf)"))
                  for leaf, end, p, finite in zip(
                      b.leaf[shown].tolist(), b.end[shown].tolist(),
                      b.persistence[shown].tolist(), b.is_finite[shown].tolist(), strict=True)]
        return x, self.nodes.scalar.astype(np.float64), segments, self.nodes.critical_type, labels


def _sha256(rows: Iterable[tuple[int, ...]]) -> str:
    """The SHA-256 of one line per row, its integers separated by spaces, fed in pieces."""
    digest = hashlib.sha256()
    lines: list[str] = []
    for row in rows:
        lines.append(" ".join(map(str, row)) + "\n")
        if len(lines) == _LINES_PER_UPDATE:
            digest.update("".join(lines).encode())
            lines.clear()
    digest.update("".join(lines).encode())
    return digest.hexdigest()


def _elder_rule(order: np.ndarray, indptr: np.ndarray, indices: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Sweeps the nodes in `order` (oldest first), joining each to its neighbours already swept
    with a union-find. A node with none starts a branch at itself; a node that joins several
    components ends the branches of all but the one with the oldest leaf. Returns the
    branches' (leaf, end, is_finite), the infinite ones (a component's oldest leaf to its last
    node) after the finite ones, and per node the leaf of the branch that goes on through it."""
    n = len(order)
    parent = list(range(n))
    oldest = [-1] * n  # per union-find root, its component's oldest leaf
    rank = [0] * n
    for position, node in enumerate(order.tolist()):
        rank[node] = position
    on_branch = np.zeros(n, dtype=np.int64)
    swept = [False] * n
    neighbours = indices.tolist()
    starts = indptr.tolist()
    leaf: list[int] = []
    end: list[int] = []

    def find(x: int) -> int:
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for node in order.tolist():
        roots = {find(y) for y in neighbours[starts[node]:starts[node + 1]] if swept[y]}
        swept[node] = True
        elder = min(roots, key=lambda r: rank[oldest[r]]) if roots else node
        oldest[node] = oldest[elder] if roots else node
        for r in roots:
            parent[r] = node
            if r != elder:
                leaf.append(oldest[r])
                end.append(node)
        on_branch[node] = oldest[node]
    finite = len(leaf)
    for node in order.tolist():
        if parent[node] == node:
            leaf.append(oldest[node])
            end.append(node)
    is_finite = np.arange(len(leaf)) < finite
    return np.array(leaf, dtype=np.int64), np.array(end, dtype=np.int64), is_finite, on_branch


def _children(root: int, indptr: np.ndarray, indices: np.ndarray) -> dict[int, list[int]]:
    """The tree of `root`'s component rooted there: each node's neighbours but its parent."""
    children: dict[int, list[int]] = {}
    stack = [(root, -1)]
    while stack:
        node, parent = stack.pop()
        children[node] = [int(c) for c in indices[indptr[node]:indptr[node + 1]] if c != parent]
        stack.extend((c, node) for c in children[node])
    return children


def _depth_first(root: int, children: Mapping[int, list[int]], key: Any) -> Iterator[int]:
    """The nodes of a rooted tree in depth-first preorder, each node's children by `key`."""
    stack = [root]
    while stack:
        node = stack.pop()
        yield node
        stack.extend(sorted(children[node], key=key, reverse=True))


# From the streamed arrays.


def _column(group: Mapping[str, np.ndarray], where: str, name: str,
            length: int | None) -> np.ndarray:
    """group[name], checked to hold `length` values (None: any)."""
    if name not in group:
        raise ActopoError(f"{where}/{name}: missing from the job's arrays "
                          f"(got {', '.join(sorted(group)) or 'none'})")
    values = np.asarray(group[name])
    if length is not None and len(values) != length:
        raise ActopoError(f"{where}/{name}: {len(values)} values, expected {length}")
    return values


def _integers(group: Mapping[str, np.ndarray], where: str, name: str,
              length: int | None) -> np.ndarray:
    """_column() of an integer array."""
    if name == "ComponentId" and name not in group:
        raise ActopoError(f"{where}/ComponentId: missing from the job's arrays; the server "
                          f"streams it beside TTK's arrays (a server older than this client "
                          f"does not)")
    values = _column(group, where, name, length)
    if not np.issubdtype(values.dtype, np.integer):
        raise ActopoError(f"{where}/{name}: dtype {values.dtype} is not an integer type")
    return values


def _component_offsets(component: np.ndarray) -> np.ndarray:
    """The first NodeId of each component, then the node count (k + 1 offsets), from
    tree_nodes/ComponentId, which must run 0, 1, ... over NodeId, each component a run."""
    steps = np.diff(component)
    if (len(component) and component[0] != 0) or ((steps != 0) & (steps != 1)).any():
        raise ActopoError("tree_nodes/ComponentId: not 0, 1, 2, ... over NodeId, each "
                          "component a run of NodeIds")
    return np.concatenate([[0], np.flatnonzero(steps) + 1, [len(component)]]).astype(np.int64)


def _global_ids(arcs: Mapping[str, np.ndarray], offsets: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each arc's component and its down and up nodes as global NodeIds: its local ids
    (downNodeId, upNodeId) plus the first NodeId of its ComponentId."""
    down_local = _integers(arcs, "tree_arcs", "downNodeId", None)
    a = len(down_local)
    up_local = _integers(arcs, "tree_arcs", "upNodeId", a)
    component = _integers(arcs, "tree_arcs", "ComponentId", a)
    components = len(offsets) - 1
    if a and (component.min() < 0 or component.max() >= components):
        i = int(np.flatnonzero((component < 0) | (component >= components))[0])
        raise ActopoError(f"tree_arcs/ComponentId: arc {i} is in component {component[i]}, but "
                          f"tree_nodes/ComponentId has {components}")
    first = offsets[component]
    count = offsets[component + 1] - first
    for name, local in (("downNodeId", down_local), ("upNodeId", up_local)):
        outside = np.flatnonzero((local < 0) | (local >= count))
        if len(outside):
            i = int(outside[0])
            raise ActopoError(f"tree_arcs/{name}: arc {i} has {local[i]}, not within the "
                              f"{count[i]} nodes of its component ({component[i]})")
    return (component.astype(np.int32), (down_local + first).astype(np.int32),
            (up_local + first).astype(np.int32))


def from_arrays(kind: str, nodes: Mapping[str, np.ndarray], arcs: Mapping[str, np.ndarray],
                segmentation: Mapping[str, np.ndarray]) -> Tree:
    """The Tree of a job's ``tree_nodes/``, ``tree_arcs/`` and ``segmentation/`` groups (arrays
    by TTK name, and the ComponentId of nodes and arcs); `kind` is the summary's "tree". Checks
    the layout it reads and the local ids it turns global (see the module's docstring)."""
    if kind not in get_args(TreeKind):
        raise ActopoError(f"tree: unknown kind '{kind}' (expected join, split or contour)")
    node_id = _column(nodes, "tree_nodes", "NodeId", None)
    n = len(node_id)
    if not np.array_equal(node_id, np.arange(n)):
        raise ActopoError("tree_nodes/NodeId: not 0, 1, 2, ... in order")
    tree_nodes = TreeNodes(
        node_id=node_id.astype(np.int32),
        **{field: _column(nodes, "tree_nodes", name, n) for field, name in (
            ("vertex", "VertexId"), ("scalar", "Scalar"), ("critical_type", "CriticalType"),
            ("region_size", "RegionSize"), ("region_span", "RegionSpan"))},
        points=_column(nodes, "tree_nodes", "Points", n).reshape(-1, 3).astype(np.float64))

    offsets = _component_offsets(_integers(nodes, "tree_nodes", "ComponentId", n))
    component, down, up = _global_ids(arcs, offsets)
    a = len(down)
    tree_arcs = TreeArcs(
        down=down, up=up,
        **{field: _column(arcs, "tree_arcs", name, a) for field, name in (
            ("segmentation_id", "SegmentationId"), ("region_size", "RegionSize"),
            ("region_span", "RegionSpan"))},
        component=component)

    segmentation_id = _column(segmentation, "segmentation", "SegmentationId", None)
    arc_of = np.full(int(tree_arcs.segmentation_id.max(initial=-1)) + 1, -1, dtype=np.int64)
    arc_of[tree_arcs.segmentation_id] = np.arange(a)
    if len(segmentation_id) and (segmentation_id.min() < 0
                                 or segmentation_id.max() >= len(arc_of)
                                 or (arc_of[segmentation_id] < 0).any()):
        raise ActopoError("segmentation/SegmentationId: a vertex's id is no arc's")
    v = len(segmentation_id)
    tree_segmentation = TreeSegmentation(
        segmentation_id=segmentation_id,
        arc=arc_of[segmentation_id].astype(np.int32),
        **{field: _column(segmentation, "segmentation", name, v) for field, name in (
            ("region_size", "RegionSize"), ("region_span", "RegionSpan"),
            ("region_type", "RegionType"))})
    return Tree(cast(TreeKind, kind), tree_nodes, tree_arcs, tree_segmentation, offsets)
