"""Distances between the persistence diagrams of several fields: the summary of a
diagram-distance job as a typed matrix, its groups by average linkage (numpy only), and its
heat map (matplotlib, with a dendrogram when scipy is there)."""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal, TypeAlias

import numpy as np

from actopo import _plot
from actopo._errors import ActopoError, InvalidArgumentError

if TYPE_CHECKING:
    from matplotlib.axes import Axes

Metric: TypeAlias = Literal["wasserstein", "bottleneck"]
"""Which of the two matrices: Wasserstein-p or bottleneck."""


@dataclass(frozen=True, eq=False)
class DistanceMatrix:
    """The exact distances between the persistence diagrams of n fields (a diagram-distance
    job; SEMANTICS.md "Distances between persistence diagrams").

    Attributes:
        fields: the fields' names, in the job's order (row and column i are fields[i]).
        wasserstein: the Wasserstein-p distances, (n, n) float64, symmetric, zero diagonal.
        bottleneck: the bottleneck distances, (n, n) float64.
        pairs: the pairs compared per field (after the threshold).
        thresholds: the absolute persistence threshold applied to each field (0: none).
        p: the Wasserstein order.
        essential: whether the infinite pairs were matched too; a distance between diagrams
            with different counts of them is then inf.

    Example::

        matrix = session.distance_matrix("all", relative_threshold=0.01)
        print(matrix.groups(3))          # a cluster label per field, by average linkage
        matrix.plot("distances.png")     # heat map (and dendrogram with scipy)
    """

    fields: list[str]
    wasserstein: np.ndarray
    bottleneck: np.ndarray
    pairs: list[int]
    thresholds: list[float]
    p: float
    essential: bool = False

    def __len__(self) -> int:
        return len(self.fields)

    def __repr__(self) -> str:
        return (f"DistanceMatrix({len(self)} fields, p={self.p:g}, "
                f"essential={self.essential})")

    def matrix(self, metric: Metric = "wasserstein") -> np.ndarray:
        """The Wasserstein-p matrix, or the bottleneck one."""
        if metric == "wasserstein":
            return self.wasserstein
        if metric == "bottleneck":
            return self.bottleneck
        raise InvalidArgumentError(f"metric: unknown metric '{metric}'; available: "
                                   "wasserstein, bottleneck")

    def linkage(self, metric: Metric = "wasserstein") -> np.ndarray:
        """The average-linkage (UPGMA) merges of the fields, in scipy's format: n - 1 rows
        (cluster a, cluster b, distance, size), clusters n + i made by row i; for
        scipy.cluster.hierarchy.dendrogram. Computed with numpy alone."""
        return average_linkage(self.matrix(metric))

    def groups(self, k: int, metric: Metric = "wasserstein") -> np.ndarray:
        """A cluster label per field (int64, 0 to k - 1): average linkage stopped at k
        clusters. Labels are numbered in the order of the fields' first members: fields[0] is
        in group 0, the first field outside it in group 1, and so on. Needs numpy only."""
        n = len(self)
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 1 <= k <= n:
            raise InvalidArgumentError(f"k: {k!r} is not a number of groups from 1 to {n}")
        merges = self.linkage(metric)
        members: dict[int, list[int]] = {i: [i] for i in range(n)}
        for step in range(n - int(k)):
            a, b = int(merges[step, 0]), int(merges[step, 1])
            members[n + step] = members.pop(a) + members.pop(b)
        labels = np.empty(n, dtype=np.int64)
        for number, group in enumerate(sorted(members.values(), key=min)):
            labels[group] = number
        return labels

    def plot(self, path_or_ax: str | os.PathLike[str] | Axes | None = None, *,
             metric: Metric = "wasserstein", title: str | None = None) -> Any:
        """Draws the matrix as a heat map, a row and a column per field named on the axes
        (matplotlib: the ``plot`` extra). When scipy is importable (it is optional, not a
        dependency) and the distances are finite, the fields are ordered as the leaves of
        their average-linkage dendrogram, drawn above the heat map; without scipy the heat map
        alone, in the fields' order.

        `path_or_ax`: a file path (PNG, SVG, PDF, ... by the suffix) to write the figure to, and
        get the path back; or a matplotlib Axes to draw on (the dendrogram goes in an inset
        above it), or None for a new figure; the heat map's Axes is returned then.
        """
        values = self.matrix(metric)
        merges = self.linkage(metric) if np.isfinite(values).all() else None
        heading = title if title is not None else (
            f"{'Wasserstein-' + format(self.p, 'g') if metric == 'wasserstein' else 'bottleneck'}"
            f" distances between {len(self)} persistence diagrams")
        if isinstance(path_or_ax, (str, os.PathLike)):
            return _plot.save_matrix(path_or_ax, values, self.fields, merges=merges,
                                     title=heading)
        return _plot.draw_matrix(values, self.fields, merges=merges, title=heading,
                                 ax=path_or_ax)


def average_linkage(distances: np.ndarray) -> np.ndarray:
    """UPGMA on a symmetric (n, n) matrix: merge the two closest clusters, the distance between
    clusters being the mean distance between their members, until one is left. Ties go to the
    lowest pair of rows. Returns scipy's linkage format (see DistanceMatrix.linkage)."""
    n = len(distances)
    current = np.array(distances, dtype=np.float64)
    size = np.ones(n)
    cluster = np.arange(n)  # the cluster each row stands for, in scipy's numbering
    active = np.ones(n, dtype=bool)
    merges = np.zeros((max(n - 1, 0), 4))
    upper = np.triu(np.ones((n, n), dtype=bool), 1)
    for step in range(n - 1):
        rows, columns = np.nonzero(upper & active[:, None] & active[None, :])
        best = int(np.argmin(current[rows, columns]))  # the first of equal ones, even of infs
        i, j = int(rows[best]), int(columns[best])
        merges[step] = [min(cluster[i], cluster[j]), max(cluster[i], cluster[j]),
                        current[i, j], size[i] + size[j]]
        merged = (size[i] * current[i] + size[j] * current[j]) / (size[i] + size[j])
        current[i, :] = merged
        current[:, i] = merged
        size[i] += size[j]
        active[j] = False
        cluster[i] = n + step
    return merges


def _matrix(summary: Mapping[str, Any], key: str, n: int) -> np.ndarray:
    """An n x n matrix of the summary; null entries (how JSON writes inf) become inf."""
    rows = summary.get(key)
    if not isinstance(rows, list) or len(rows) != n \
            or any(not isinstance(r, list) or len(r) != n for r in rows):
        raise ActopoError(f"diagram-distance summary: '{key}' is not a {n} x {n} matrix")
    return np.array([[np.inf if v is None else float(v) for v in row] for row in rows],
                    dtype=np.float64).reshape(n, n)


def from_summary(summary: Mapping[str, Any]) -> DistanceMatrix:
    """The DistanceMatrix of a diagram-distance job's summary."""
    fields = summary.get("fields")
    if not isinstance(fields, list):
        raise ActopoError("diagram-distance summary: no 'fields' list")
    n = len(fields)
    return DistanceMatrix(fields=[str(f) for f in fields],
                          wasserstein=_matrix(summary, "wasserstein", n),
                          bottleneck=_matrix(summary, "bottleneck", n),
                          pairs=[int(v) for v in summary.get("pairs", [])],
                          thresholds=[float(v) for v in summary.get("thresholds", [])],
                          p=float(summary.get("p", 2.0)),
                          essential=bool(summary.get("essential", False)))
