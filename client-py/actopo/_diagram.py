"""Persistence diagrams: the ``diagram/`` and ``persistence_curve/`` arrays of a
persistence-diagram job as one typed object, one entry per pair, TTK's diagonal set apart.

The server streams TTK's diagram grid (see the proto's ResultChunk): two points per pair, birth
then death, a line per pair, and last TTK's diagonal, a line from the first point to the last
pair's birth point, so the lines come with ``Connectivity`` as well as ``Offsets``. The pairs are
read by position (pair i is points 2i and 2i + 1, line i), checked against both, and the diagonal
is rebuilt by TTK's rule when the grid is wanted back (PersistenceDiagram.ttk_grid()).
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, NamedTuple, TypeAlias

import numpy as np

from actopo import _plot, _vtk
from actopo._errors import ActopoError

if TYPE_CHECKING:
    from matplotlib.axes import Axes

Embedding: TypeAlias = Literal["diagram", "domain"]
"""Where TTK puts the diagram's points: in the birth-death plane, or at the vertices."""

CURVE_TYPES = (0, 1, 2, -1)
"""The persistence curves the server sends: one per pair type, then -1, all pairs."""


class PersistenceCurve(NamedTuple):
    """TTK's persistence curve of one pair type: the distinct persistence values, ascending
    (float64), and how many pairs of that type have at least that persistence (int32)."""

    persistence: np.ndarray
    number_of_pairs: np.ndarray


class DiagramGrid(NamedTuple):
    """TTK's diagram output as plain arrays: points (p, 3) float64, lines (m, 2) point ids (a
    VTK_LINE cell each, TTK's diagonal last), and the point and cell arrays by TTK's names."""

    points: np.ndarray
    lines: np.ndarray
    point_data: dict[str, np.ndarray]
    cell_data: dict[str, np.ndarray]


def _interleave(first: np.ndarray, second: np.ndarray) -> np.ndarray:
    """first[0], second[0], first[1], second[1], ...: a pair's two points, one after the other."""
    return np.stack([first, second], axis=1).reshape(-1, *first.shape[1:])


def persistence_curve(persistence: np.ndarray) -> PersistenceCurve:
    """The persistence curve of these pairs, as the server's ``persistence_curve/`` arrays hold
    TTK's: each distinct persistence, ascending, and the number of pairs with at least it."""
    ordered = np.sort(np.asarray(persistence, dtype=np.float64))
    values = np.unique(ordered)
    alive = len(ordered) - np.searchsorted(ordered, values, side="left")
    return PersistenceCurve(values, alive.astype(np.int32))


def _curves_of(pair_type: np.ndarray, persistence: np.ndarray) -> dict[int, PersistenceCurve]:
    """The curve of each pair type and of all pairs (-1), computed from the pairs."""
    return {kind: persistence_curve(persistence if kind == -1 else persistence[pair_type == kind])
            for kind in CURVE_TYPES}


@dataclass(frozen=True, eq=False)
class PersistenceDiagram:
    """The pairs of a persistence diagram (TTK's PersistenceDiagram), one entry per pair in the
    server's order (by the vertex order of the birth vertex), without TTK's diagonal.

    A pair of type k (0: minimum - 1-saddle, 1: 1-saddle - 2-saddle, 2: 2-saddle - maximum) is
    born at a critical k-cell and dies at a critical (k+1)-cell; an infinite pair never dies
    and TTK puts its death at the global maximum. Each critical cell is named by its highest
    vertex (input id).

    Attributes:
        pair_identifier: TTK's PairIdentifier (int32), the pair's position in the diagram.
        pair_type: 0, 1 or 2 (int32).
        birth_vertex, death_vertex: the vertices of the two critical cells (int32 input ids).
        birth_type, death_type: their CriticalType (int32): 0 minimum, 1 1-saddle,
            2 2-saddle, 3 maximum.
        birth, death: the scalar values at those vertices (float64).
        persistence: death - birth as TTK reports it (float64).
        is_finite: False for the infinite pairs (bool).
        birth_coordinates, death_coordinates: the vertices' positions, (n, 3) float32.
        birth_point, death_point: where TTK draws the pair, (n, 3) float64: (birth, birth, 0)
            and (birth, death, 0), or the vertices' positions with embedding "domain".
        embedding: "diagram" (the birth-death plane) or "domain" (at the vertices).
        curves: TTK's persistence curves by pair type, -1 for all pairs.

    Example::

        diagram = session.run("persistence-diagram").diagram
        print(diagram.counts_by_type(), diagram.pairs_sha256())
        strong = diagram.above(0.01 * (field.max - field.min))   # the pairs a 1% cut keeps
    """

    pair_identifier: np.ndarray
    pair_type: np.ndarray
    birth_vertex: np.ndarray
    death_vertex: np.ndarray
    birth_type: np.ndarray
    death_type: np.ndarray
    birth: np.ndarray
    death: np.ndarray
    persistence: np.ndarray
    is_finite: np.ndarray
    birth_coordinates: np.ndarray
    death_coordinates: np.ndarray
    birth_point: np.ndarray
    death_point: np.ndarray
    embedding: Embedding
    curves: Mapping[int, PersistenceCurve]

    def __len__(self) -> int:
        return len(self.pair_type)

    def __repr__(self) -> str:
        return (f"PersistenceDiagram({len(self)} pairs, {self.counts_by_type()}, "
                f"embedding={self.embedding!r})")

    def counts_by_type(self) -> dict[str, int]:
        """Pairs per type as the job's summary counts them: "k" the finite pairs of type k,
        "k_infinite" the infinite ones; types without pairs are left out."""
        counts = {}
        for kind in range(3):
            of_kind = self.pair_type == kind
            for key, selected in ((str(kind), of_kind & self.is_finite),
                                  (f"{kind}_infinite", of_kind & ~self.is_finite)):
                if selected.any():
                    counts[key] = int(selected.sum())
        return counts

    def sorted_pairs(self) -> np.ndarray:
        """(n, 4) int64 rows (type, birth vertex, death vertex, finite 1 or 0), sorted as
        integer tuples: the lines of pairs_sha256(), and of expected-ttk.json's ``lines``."""
        table = np.stack([self.pair_type, self.birth_vertex, self.death_vertex,
                          self.is_finite], axis=1).astype(np.int64).reshape(-1, 4)
        return table[np.lexsort(table.T[::-1])]

    def pairs_sha256(self) -> str:
        """The SHA-256 of one line "TYPE BIRTH DEATH FINITE\\n" per pair, sorted as integer
        tuples: computed here from the arrays, it equals the summary's ``pairs_sha256`` and
        TTK's digest in expected-ttk.json."""
        text = "".join(f"{t} {b} {d} {f}\n" for t, b, d, f in self.sorted_pairs().tolist())
        return hashlib.sha256(text.encode()).hexdigest()

    def _take(self, index: np.ndarray) -> PersistenceDiagram:
        """The pairs at `index`; their curves are computed anew, those the server sent being
        of the whole diagram."""
        arrays = {f.name: getattr(self, f.name)[index] for f in dataclasses.fields(self)
                  if f.name not in ("embedding", "curves")}
        return dataclasses.replace(self, **arrays, curves=_curves_of(arrays["pair_type"],
                                                                    arrays["persistence"]))

    def above(self, threshold: float) -> PersistenceDiagram:
        """The pairs with persistence >= `threshold` (the infinite ones by their persistence
        as TTK reports it, up to the global maximum), in the same order, with their curves."""
        return self._take(np.flatnonzero(self.persistence >= threshold))

    def ttk_grid(self) -> DiagramGrid:
        """TTK's diagram output: two points per pair and a line between them, then, in the
        "diagram" embedding, TTK's diagonal: a line from the first point to the last pair's
        birth point, PairIdentifier and PairType -1, Birth 0, IsFinite 0 and twice the first
        pair's persistence. For a job's diagram its arrays equal the streamed ones."""
        n = len(self)
        lines = np.arange(2 * n, dtype=np.int64).reshape(-1, 2)
        cells: dict[str, np.ndarray] = {
            "PairIdentifier": self.pair_identifier.astype(np.int32),
            "PairType": self.pair_type.astype(np.int32),
            "Persistence": self.persistence.astype(np.float64),
            "Birth": self.birth.astype(np.float64),
            "IsFinite": self.is_finite.astype(np.int8),
        }
        if n and self.embedding == "diagram":
            lines = np.vstack([lines, [[0, 2 * (n - 1)]]])
            diagonal = {"PairIdentifier": -1, "PairType": -1,
                        "Persistence": 2 * self.persistence[0], "Birth": 0, "IsFinite": 0}
            cells = {k: np.append(v, np.array(diagonal[k], dtype=v.dtype))
                     for k, v in cells.items()}
        points = {
            "ttkVertexScalarField": _interleave(self.birth_vertex, self.death_vertex),
            "CriticalType": _interleave(self.birth_type, self.death_type),
            "Coordinates": _interleave(self.birth_coordinates, self.death_coordinates),
        }
        return DiagramGrid(_interleave(self.birth_point, self.death_point).reshape(-1, 3),
                           lines, points, cells)

    def to_pyvista(self) -> Any:
        """TTK's diagram output (ttk_grid()) as a pyvista UnstructuredGrid of VTK_LINE cells
        (needs the ``pyvista`` extra)."""
        return _vtk.line_grid(*self.ttk_grid())

    def write(self, prefix: str) -> list[str]:
        """Writes what actopo-bench --output writes for the diagram: PREFIX_diagram.vtu (TTK's
        grid; pyvista, else meshio) and PREFIX_persistence_curve.csv (columns PairType,
        Persistence, NumberOfPairs). Returns the paths written."""
        grid = _vtk.write_line_grid(f"{prefix}_diagram.vtu", *self.ttk_grid())
        rows = ["PairType,Persistence,NumberOfPairs\n"]
        for kind in CURVE_TYPES:
            curve = self.curves[kind]
            rows += [f"{kind},{p:.17g},{c}\n" for p, c in zip(
                curve.persistence.tolist(), curve.number_of_pairs.tolist(), strict=True)]
        table = Path(f"{prefix}_persistence_curve.csv")
        table.write_text("".join(rows))
        return [grid, str(table)]

    def plot(self, ax: Axes | None = None, *, threshold: float | None = None,
             title: str | None = None) -> Axes:
        """Draws the diagram with matplotlib (the ``plot`` extra): birth on x, death on y, a
        colour and marker per pair type, infinite pairs as stars, the diagonal, and with
        `threshold` the line death = birth + threshold. Into `ax`, else a new Figure (no
        pyplot); returns the axes."""
        return _plot.draw(self.birth, self.death, self.pair_type, self.is_finite,
                          threshold=threshold, title=title, ax=ax)

    def save_plot(self, path: str | os.PathLike[str], *, threshold: float | None = None,
                  title: str | None = None) -> str:
        """plot() into a file (PNG, SVG, PDF, ... by the suffix); returns the path."""
        return _plot.save(path, self.birth, self.death, self.pair_type, self.is_finite,
                          threshold=threshold, title=title)


def _column(group: Mapping[str, np.ndarray], name: str, length: int | None,
            where: str = "diagram") -> np.ndarray:
    """group[name], checked to hold `length` values (None: any); an array of no values may
    be left out, as the server leaves out those of an empty diagram."""
    if name not in group:
        if length == 0:
            return np.zeros(0)
        raise ActopoError(f"{where}/{name}: missing from the job's arrays "
                          f"(got {', '.join(sorted(group)) or 'none'})")
    values = np.asarray(group[name])
    if length is not None and len(values) != length:
        raise ActopoError(f"{where}/{name}: {len(values)} values, expected {length}")
    return values


def _curves(group: Mapping[str, np.ndarray], pair_type: np.ndarray,
            persistence: np.ndarray) -> dict[int, PersistenceCurve]:
    """The curves of a ``persistence_curve/`` group (PairType, Persistence, NumberOfPairs:
    the curves one after another), or computed from the pairs when the group is empty."""
    if not group:
        return _curves_of(pair_type, persistence)
    kinds = _column(group, "PairType", None, "persistence_curve")
    values = _column(group, "Persistence", len(kinds), "persistence_curve")
    counts = _column(group, "NumberOfPairs", len(kinds), "persistence_curve")
    return {kind: PersistenceCurve(values[kinds == kind].astype(np.float64),
                                   counts[kinds == kind].astype(np.int32))
            for kind in CURVE_TYPES}


def from_arrays(diagram: Mapping[str, np.ndarray],
                curves: Mapping[str, np.ndarray] | None = None) -> PersistenceDiagram:
    """The PersistenceDiagram of a job's ``diagram/`` group (arrays by TTK name) and its
    ``persistence_curve/`` group (the curves are computed from the pairs when it is absent).

    Checks the layout it reads by position: two points per pair, one line per pair, and the
    diagonal last exactly when its PairIdentifier is -1."""
    identifiers = np.asarray(diagram.get("PairIdentifier", np.zeros(0, dtype=np.int32)))
    lines = len(identifiers)
    has_diagonal = lines > 0 and int(identifiers[-1]) == -1
    n = lines - int(has_diagonal)
    offsets = _column(diagram, "Offsets", lines + 1 if lines else 0)
    if lines and not np.array_equal(offsets[:n + 1], 2 * np.arange(n + 1)):
        raise ActopoError("diagram/Offsets: the pairs' lines are not two consecutive points "
                          "each")
    if "Connectivity" in diagram:
        expected = np.arange(2 * n)
        if has_diagonal:
            expected = np.concatenate([expected, [0, 2 * (n - 1)]])
        if not np.array_equal(np.asarray(diagram["Connectivity"]), expected):
            raise ActopoError("diagram/Connectivity: not a line per pair's two points and "
                              "TTK's diagonal")
    per_line = {name: _column(diagram, name, lines)[:n]
                for name in ("PairIdentifier", "PairType", "Persistence", "Birth", "IsFinite")}
    per_point = {name: _column(diagram, name, 2 * n)
                 for name in ("Points", "ttkVertexScalarField", "CriticalType", "Coordinates")}
    points = per_point["Points"].reshape(-1, 3).astype(np.float64)
    birth = per_line["Birth"].astype(np.float64)
    persistence = per_line["Persistence"].astype(np.float64)
    embedding: Embedding = "diagram" if has_diagonal or not n else "domain"
    # The diagram embedding draws the death at (birth, death): exact. At the vertices the
    # death is only known as birth + persistence, which may differ from it in the last bit.
    death = points[1::2, 1].copy() if embedding == "diagram" else birth + persistence
    coordinates = per_point["Coordinates"].reshape(-1, 3)
    pair_type = per_line["PairType"].astype(np.int32)
    return PersistenceDiagram(
        pair_identifier=per_line["PairIdentifier"].astype(np.int32),
        pair_type=pair_type,
        birth_vertex=per_point["ttkVertexScalarField"][0::2].astype(np.int32),
        death_vertex=per_point["ttkVertexScalarField"][1::2].astype(np.int32),
        birth_type=per_point["CriticalType"][0::2].astype(np.int32),
        death_type=per_point["CriticalType"][1::2].astype(np.int32),
        birth=birth, death=death, persistence=persistence,
        is_finite=per_line["IsFinite"].astype(bool),
        birth_coordinates=coordinates[0::2].astype(np.float32),
        death_coordinates=coordinates[1::2].astype(np.float32),
        birth_point=points[0::2], death_point=points[1::2],
        embedding=embedding, curves=_curves(curves or {}, pair_type, persistence))
