"""Persistence diagrams drawn with matplotlib (the ``plot`` extra), birth against death.

It takes the pairs' arrays, not the PersistenceDiagram, so that _diagram depends on this module
and not the other way round. No pyplot: a Figure of its own draws without a display and leaves
matplotlib's global state (the backend, the current figure) as the caller had it.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

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


def _figure() -> Figure:
    try:
        from matplotlib.figure import Figure
    except ImportError:
        raise ImportError("plotting needs matplotlib: pip install 'actopo[plot]'") from None
    return Figure(figsize=(7.0, 7.0), layout="constrained")


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
