"""Drawings with matplotlib (the ``plot`` extra): persistence diagrams, birth against death,
distance matrices as heat maps, with a dendrogram when scipy is there, and merge and contour
trees, each node at its value.

It takes plain arrays, not the PersistenceDiagram, the DistanceMatrix or the Tree, so that
_diagram, _distances and _tree depend on this module and not the other way round. No pyplot:
a Figure of its own draws without a display and leaves matplotlib's global state (the backend,
the current figure) as the caller had it.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

PAIR_STYLES = {
    0: ("tab:blue", "o", "minimum - 1-saddle"),
    1: ("tab:orange", "s", "1-saddle - 2-saddle"),
    2: ("tab:green", "^", "2-saddle - maximum"),
}
"""Pair type -> (colour, marker, what the pair joins)."""


def _figure(size: float = 7.0, height: float | None = None) -> Figure:
    """A Figure of its own, `size` inches wide and `height` (default: as wide) high."""
    try:
        from matplotlib.figure import Figure
    except ImportError:
        raise ImportError("plotting needs matplotlib: pip install 'actopo[plot]'") from None
    return Figure(figsize=(size, size if height is None else height), layout="constrained")


def draw(birth: np.ndarray, death: np.ndarray, pair_type: np.ndarray, is_finite: np.ndarray, *,
         threshold: float | None = None, title: str | None = None,
         ax: Axes | None = None) -> Axes:
    """Draws the pairs as points (birth, death), one colour and marker per type; an infinite
    pair, drawn at its death (the global maximum), gets a large star edged in black so that it
    does not pass for a finite pair that dies there. Adds the diagonal and, with `threshold`,
    the line death = birth + threshold over a shaded band: the pairs in the band are those a
    simplification at that persistence removes."""
    ax = ax if ax is not None else _figure().add_subplot()
    values = np.concatenate([birth, death]) if len(birth) else np.zeros(1)
    low, high = float(values.min()), float(values.max())
    margin = 0.03 * (high - low) or 1.0
    span = np.array([low - margin, high + margin])
    ax.plot(span, span, color="0.3", linewidth=1.0, label="diagonal")
    if threshold is not None:
        ax.fill_between(span, span, span + threshold, color="0.88", linewidth=0)
        ax.plot(span, span + threshold, color="tab:red", linestyle="--", linewidth=1.0,
                label=f"death = birth + {threshold:.4g}")
    for kind, (colour, marker, joins) in PAIR_STYLES.items():
        finite = (pair_type == kind) & is_finite
        infinite = (pair_type == kind) & ~is_finite
        if finite.any():
            ax.scatter(birth[finite], death[finite], s=14, c=colour, marker=marker, alpha=0.75,
                       linewidths=0, label=f"type {kind}: {joins} ({finite.sum()})")
        if infinite.any():
            ax.scatter(birth[infinite], death[infinite], s=160, c=colour, marker="*",
                       edgecolors="black", linewidths=0.8, zorder=3,
                       label=f"type {kind}, infinite ({infinite.sum()})")
    ax.set_xlim(*span)
    ax.set_ylim(*span)
    ax.set_aspect("equal")
    ax.set_xlabel("birth")
    ax.set_ylabel("death")
    ax.grid(True, color="0.93", linewidth=0.6)
    ax.legend(loc="lower right", fontsize="small")
    ax.set_title(title if title is not None else f"persistence diagram: {len(birth)} pairs")
    return ax


def save(path: str | os.PathLike[str], birth: np.ndarray, death: np.ndarray,
         pair_type: np.ndarray, is_finite: np.ndarray, *, threshold: float | None = None,
         title: str | None = None, dpi: int = 150) -> str:
    """draw() on a figure of its own, written to `path` (PNG, SVG, PDF, ... by the suffix);
    returns the path."""
    figure = _figure()
    draw(birth, death, pair_type, is_finite, threshold=threshold, title=title,
         ax=figure.add_subplot())
    figure.savefig(path, dpi=dpi)
    return str(path)


ANNOTATED_FIELDS = 12
"""Up to this many fields, each cell of a distance heat map shows its value."""


def _leaf_order(merges: np.ndarray | None) -> tuple[list[int] | None, Any]:
    """The leaves of the dendrogram of `merges` (scipy's linkage format), left to right, and
    scipy's dendrogram function; (None, None) without merges or without scipy."""
    if merges is None or len(merges) == 0:
        return None, None
    try:
        from scipy.cluster.hierarchy import dendrogram
    except ImportError:
        return None, None
    leaves: list[int] = dendrogram(merges, no_plot=True)["leaves"]
    return leaves, dendrogram


def draw_matrix(values: np.ndarray, names: list[str], *, merges: np.ndarray | None = None,
                title: str | None = None, ax: Axes | None = None) -> Axes:
    """Draws an (n, n) matrix of distances between named fields as a heat map with a colour
    bar, the names on both axes, and the values in the cells when there are few. With
    `merges` (a linkage of the fields) and scipy, the rows and columns follow the dendrogram's
    leaves and the dendrogram is drawn in an inset above the heat map; non-finite distances
    are left blank."""
    ax = ax if ax is not None else _figure(max(7.0, 3.0 + 0.4 * len(names))).add_subplot()
    order, dendrogram = _leaf_order(merges)
    index = np.arange(len(names)) if order is None else np.array(order)
    shown = np.asarray(values, dtype=np.float64)[np.ix_(index, index)]
    labels = [names[i] for i in index]
    image = ax.imshow(np.where(np.isfinite(shown), shown, np.nan), cmap="viridis",
                      aspect="auto", interpolation="nearest")
    ax.figure.colorbar(image, ax=ax, fraction=0.046, pad=0.02, label="distance")
    ax.set_xticks(range(len(labels)), labels, rotation=90)
    ax.set_yticks(range(len(labels)), labels)
    if len(labels) <= ANNOTATED_FIELDS:
        finite = shown[np.isfinite(shown)]
        middle = (finite.min() + finite.max()) / 2 if len(finite) else 0.0
        for (row, column), value in np.ndenumerate(shown):
            ax.text(column, row, f"{value:.3g}", ha="center", va="center", fontsize="x-small",
                    color="black" if value > middle else "white")
    top = ax
    if dendrogram is not None:
        top = ax.inset_axes((0.0, 1.02, 1.0, 0.22))
        dendrogram(merges, ax=top, no_labels=True, link_color_func=lambda _: "0.3")
        top.set_xticks([])
        top.set_ylabel("average\nlinkage", fontsize="small")
        for side in ("top", "right", "bottom"):
            top.spines[side].set_visible(False)
    top.set_title(title if title is not None else f"distances between {len(names)} fields")
    return ax


def save_matrix(path: str | os.PathLike[str], values: np.ndarray, names: list[str], *,
                merges: np.ndarray | None = None, title: str | None = None,
                dpi: int = 150) -> str:
    """draw_matrix() on a figure of its own, written to `path`; returns the path."""
    figure = _figure(max(7.0, 3.0 + 0.4 * len(names)))
    draw_matrix(values, names, merges=merges, title=title, ax=figure.add_subplot())
    # The dendrogram's inset lies outside the heat map's box, where the layout does not look.
    figure.savefig(path, dpi=dpi, bbox_inches="tight")
    return str(path)


NODE_STYLES = {
    0: ("tab:blue", "v", "minimum"),
    1: ("tab:orange", "s", "1-saddle"),
    2: ("tab:green", "D", "2-saddle"),
    3: ("tab:red", "^", "maximum"),
    4: ("tab:purple", "X", "degenerate"),
    5: ("0.5", "o", "regular"),
}
"""A tree node's CriticalType -> (colour, marker, name)."""


def _tree_width(x: np.ndarray) -> float:
    """Inches for a tree whose leaves are at x = 0, 1, ...: 7, up to 18 for many leaves."""
    leaves = float(x.max()) + 1 if len(x) else 1.0
    return min(18.0, max(7.0, 0.12 * leaves))


def draw_tree(x: np.ndarray, y: np.ndarray, arcs: np.ndarray, critical_type: np.ndarray,
              labels: list[tuple[int, int, str]], *, elbows: bool, title: str,
              ax: Axes | None = None) -> Axes:
    """Draws a tree: node i at (x[i], y[i]) with the marker of its CriticalType, each arc (a
    row of `arcs`: a child and its parent) as a segment, or with `elbows` as an elbow: up or
    down from the child to the parent's value, then across to the parent, so that a branch's
    height is its persistence. For each (leaf, end, text) of `labels` the text is written along
    the branch from its leaf away from its end (a branch's persistence: below a minimum, above
    a maximum). The x axis means nothing but the order of the leaves, so it has no ticks."""
    from matplotlib.collections import LineCollection

    ax = ax if ax is not None else _figure(_tree_width(x), 6.0).add_subplot()
    child, parent = arcs.reshape(-1, 2).T
    start, target = np.stack([x[child], y[child]], 1), np.stack([x[parent], y[parent]], 1)
    corner = np.stack([x[child], y[parent]], 1) if elbows else target
    lines = np.stack([start, corner, target], axis=1)
    ax.add_collection(LineCollection(list(lines), colors="0.35", linewidths=1.0, zorder=1))
    for kind, (colour, marker, name) in NODE_STYLES.items():
        selected = critical_type == kind
        if selected.any():
            ax.scatter(x[selected], y[selected], s=22, c=colour, marker=marker, zorder=2,
                       linewidths=0, label=f"{name} ({selected.sum()})")
    for leaf, end, text in labels:
        below = y[leaf] <= y[end]
        # Rotated to read upwards: anchored at its end below a leaf, at its start above one.
        ax.annotate(text, (x[leaf], y[leaf]), xytext=(0, -5 if below else 5),
                    textcoords="offset points", fontsize="x-small", rotation=90,
                    rotation_mode="anchor", ha="right" if below else "left", va="center",
                    color="0.15")
    low, high = (float(y.min()), float(y.max())) if len(y) else (0.0, 1.0)
    margin = 0.12 * (high - low) or 1.0  # room for the labels
    ax.set_xlim(-1.0, (float(x.max()) if len(x) else 0.0) + 1.0)
    ax.set_ylim(low - margin, high + margin)
    ax.set_xticks([])
    ax.set_xlabel("leaves" + (" (beside each: its branch's persistence)" if labels else ""))
    ax.set_ylabel("scalar")
    ax.grid(True, axis="y", color="0.93", linewidth=0.6)
    ax.legend(loc="best", fontsize="small")
    ax.set_title(title)
    return ax


def save_tree(path: str | os.PathLike[str], x: np.ndarray, y: np.ndarray, arcs: np.ndarray,
              critical_type: np.ndarray, labels: list[tuple[int, int, str]], *, elbows: bool,
              title: str, dpi: int = 150) -> str:
    """draw_tree() on a figure of its own, written to `path`; returns the path."""
    figure = _figure(_tree_width(x), 6.0)
    draw_tree(x, y, arcs, critical_type, labels, elbows=elbows, title=title,
              ax=figure.add_subplot())
    figure.savefig(path, dpi=dpi)
    return str(path)
