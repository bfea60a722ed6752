"""The trajectories of a tracking job (SEMANTICS.md "Tracking over time"): TTK's tracking output
as numpy arrays, a pyvista PolyData, and a plot of the trajectories over time."""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from matplotlib.axes import Axes

CRITICAL_TYPE_NAMES = {0: "minimum (type 0 pairs)", 1: "1-saddle (type 1 pairs)",
                       3: "maximum (type 2 pairs)"}
"""A trajectory's points are its pairs' extremum-side vertices: CriticalType by pair type."""


@dataclass(frozen=True)
class Trajectories:
    """The pairs of consecutive fields matched and chained into trajectories.

    Attributes:
        fields: the steps, in time order (TimeStep i is fields[i]).
        p: the Wasserstein order of the matchings.
        step_wasserstein: the distance between steps t and t + 1, the cost of their optimal
            matching, (steps - 1,) float64.
        points: (k, 3) float64, a point per tracked pair and step, at its vertex.
        time_step, critical_type, scalar, vertex_id: per point (TTK's TimeStep, CriticalType,
            Scalar, VertexId).
        lines: (m, 2) int64, the two points of each link.
        component, matching, cost, component_length: per link (TTK's ConnectedComponentId,
            MatchingIdentifier, Cost, ComponentLength).

    Example::

        tracks = session.run("tracking", fields="all").tracking
        tracks.plot("tracks.png")            # scalar against time, a line per trajectory
        grid = tracks.to_pyvista()           # the polylines, for a 3D view over the mesh
    """

    fields: list[str]
    p: float
    step_wasserstein: np.ndarray
    points: np.ndarray
    time_step: np.ndarray
    critical_type: np.ndarray
    scalar: np.ndarray
    vertex_id: np.ndarray
    lines: np.ndarray
    component: np.ndarray
    matching: np.ndarray
    cost: np.ndarray
    component_length: np.ndarray

    def __len__(self) -> int:
        """The number of trajectories."""
        return int(self.component.max()) + 1 if len(self.component) else 0

    def trajectory(self, index: int) -> np.ndarray:
        """The points of trajectory `index`, in time order (indices into the point arrays)."""
        links = self.lines[self.component == index]
        if len(links) == 0:
            raise IndexError(f"trajectory {index} is not among the {len(self)}")
        return np.concatenate([links[:, 0], links[-1:, 1]])

    def to_pyvista(self) -> Any:
        """The trajectories as a pyvista PolyData (the ``pyvista`` extra): a line per link,
        TTK's array names on points and lines."""
        import pyvista as pv

        cells = np.column_stack([np.full(len(self.lines), 2), self.lines]).ravel()
        poly = pv.PolyData(self.points, lines=cells)
        for name, values in (("TimeStep", self.time_step), ("CriticalType", self.critical_type),
                             ("Scalar", self.scalar), ("VertexId", self.vertex_id)):
            poly.point_data[name] = values
        for name, values in (("ConnectedComponentId", self.component),
                             ("MatchingIdentifier", self.matching), ("Cost", self.cost),
                             ("ComponentLength", self.component_length)):
            poly.cell_data[name] = values
        return poly

    def plot(self, path_or_ax: str | os.PathLike[str] | Axes | None = None, *,
             min_length: int = 1, title: str | None = None) -> Any:
        """Draws each trajectory of at least `min_length` links as a line of its pairs'
        extremum values against the time step, coloured by critical type (matplotlib: the
        ``plot`` extra). `path_or_ax`: a file to write (its path comes back), an Axes to draw
        on, or None for a new figure (the Axes comes back)."""
        from matplotlib.figure import Figure

        figure, path = None, None
        if path_or_ax is None or isinstance(path_or_ax, (str, os.PathLike)):
            figure = Figure(figsize=(8, 5), layout="constrained")
            ax, path = figure.add_subplot(), path_or_ax
        else:
            ax = path_or_ax
        colours = {0: "tab:blue", 1: "tab:green", 3: "tab:red"}
        labelled: set[int] = set()
        for index in range(len(self)):
            links = self.lines[self.component == index]
            if len(links) < min_length:
                continue
            points = np.concatenate([links[:, 0], links[-1:, 1]])
            kind = int(self.critical_type[points[0]])
            ax.plot(self.time_step[points], self.scalar[points], color=colours.get(kind, "0.5"),
                    linewidth=0.6, alpha=0.7,
                    label=None if kind in labelled else CRITICAL_TYPE_NAMES.get(kind, str(kind)))
            labelled.add(kind)
        ax.set_xticks(range(len(self.fields)), self.fields, rotation=90)
        ax.set_ylabel("scalar at the pair's extremum")
        if labelled:
            ax.legend(fontsize="small", loc="upper right")
        ax.set_title(title if title is not None else
                     f"{len(self)} trajectories through {len(self.fields)} steps")
        if figure is not None and path is not None:
            figure.savefig(path, dpi=150)
            return str(path)
        return ax


def from_result(summary: dict[str, Any], group: dict[str, np.ndarray]) -> Trajectories:
    """The Trajectories of a tracking job's summary and `tracking` arrays."""
    connectivity = group.get("Connectivity", np.arange(len(group.get("Points", []))))
    return Trajectories(
        fields=list(summary["fields"]), p=float(summary["p"]),
        step_wasserstein=np.asarray(summary["step_wasserstein"], dtype=np.float64),
        points=np.asarray(group["Points"], dtype=np.float64).reshape(-1, 3),
        time_step=group["TimeStep"], critical_type=group["CriticalType"],
        scalar=group["Scalar"], vertex_id=group["VertexId"],
        lines=np.asarray(connectivity, dtype=np.int64).reshape(-1, 2),
        component=group["ConnectedComponentId"], matching=group["MatchingIdentifier"],
        cost=group["Cost"], component_length=group["ComponentLength"])
