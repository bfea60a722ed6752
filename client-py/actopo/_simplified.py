"""Simplified fields: the ``simplified/`` arrays of a topological-simplification job (or of a
morse-smale job run with a threshold) as one typed object, with the digests of the summary
computed here.

The server streams TTK's TopologicalSimplification outputs (see the proto's ResultChunk):
``simplified/<field>``, the simplified field (float64), and ``simplified/<field>_Order``, its
vertex order (int32, TTK's array of that name), one value per vertex in input ids. The field's
name is the one whose ``_Order`` array is beside it.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from actopo._errors import ActopoError

ORDER_SUFFIX = "_Order"
"""TTK's name of a field's vertex order array: "<field>_Order"."""

_LINES_PER_UPDATE = 1 << 16
"""Vertices formatted at a time into a digest, so that the text is never held whole."""


def _lines_sha256(values: np.ndarray, line: Callable[[int, float | int], str]) -> str:
    """The SHA-256 of line(vertex, value) for every vertex in ascending id, fed in pieces."""
    digest = hashlib.sha256()
    for start in range(0, len(values), _LINES_PER_UPDATE):
        piece = values[start:start + _LINES_PER_UPDATE].tolist()
        digest.update("".join(line(start + i, x) for i, x in enumerate(piece)).encode())
    return digest.hexdigest()


@dataclass(frozen=True, eq=False)
class SimplifiedField:
    """A scalar field as TTK's TopologicalSimplification leaves it: the extrema of the pairs
    below the persistence threshold removed, the others (the constraints) kept.

    Attributes:
        name: the scalar field's name; TTK's output keeps it, and adds ``<name>_Order``.
        values: the simplified field, one value per vertex in input ids (float64).
        order: its vertex order (int32): vertex v is the order[v]-th lowest of the
            simplified field, ties broken as TTK breaks them (TTK's ``<name>_Order``).

    Example::

        simplified = session.run("topological-simplification",
                                 parameters={"relative_threshold": "0.05"}).simplified
        print(simplified.scalars_sha256(), len(simplified.changed_vertices(original)))
    """

    name: str
    values: np.ndarray
    order: np.ndarray

    def __len__(self) -> int:
        return len(self.values)

    def __repr__(self) -> str:
        return f"SimplifiedField({self.name!r}, {len(self)} vertices)"

    @property
    def order_name(self) -> str:
        """The name of the order array: ``<name>_Order``."""
        return self.name + ORDER_SUFFIX

    def scalars_sha256(self) -> str:
        """The SHA-256 of one line "<vertex id> <value as %.17g>\\n" per vertex in ascending id:
        computed here from the values, it equals the summary's ``scalars_sha256`` and TTK's
        (tests/ttk_reference/simplification-ttk.json)."""
        return _lines_sha256(self.values, lambda v, x: f"{v} {x:.17g}\n")

    def order_sha256(self) -> str:
        """The SHA-256 of one line "<vertex id> <order>\\n" per vertex in ascending id: the
        summary's ``order_sha256``, TTK's for its ``<name>_Order`` array."""
        return _lines_sha256(self.order, lambda v, o: f"{v} {o}\n")

    def changed_vertices(self, original: np.ndarray) -> np.ndarray:
        """The vertices (ascending input ids) whose simplified value differs from `original`,
        the field before simplification (one value per vertex, compared as float64); their
        count is the summary's ``changed_values``."""
        before = np.asarray(original, dtype=np.float64).reshape(-1)
        if len(before) != len(self):
            raise ValueError(f"original: {len(before)} values, the simplified field "
                             f"'{self.name}' has {len(self)}")
        return np.flatnonzero(self.values != before)

    def point_data(self) -> dict[str, np.ndarray]:
        """The two arrays by TTK's names, as TTK's filter adds them to its output grid:
        ``{name: values, name + "_Order": order}``."""
        return {self.name: self.values, self.order_name: self.order}


def from_arrays(group: Mapping[str, np.ndarray]) -> SimplifiedField:
    """The SimplifiedField of a job's ``simplified/`` group (arrays by TTK name): the field and
    its ``_Order`` array, one value per vertex each."""
    names = [name for name in group if name + ORDER_SUFFIX in group]
    if len(names) != 1 or len(group) != 2:
        raise ActopoError(f"simplified/: expected a field and its {ORDER_SUFFIX} array, got "
                          f"{', '.join(sorted(group)) or 'none'}")
    name = names[0]
    values = np.asarray(group[name], dtype=np.float64).reshape(-1)
    order = np.asarray(group[name + ORDER_SUFFIX], dtype=np.int32).reshape(-1)
    if len(order) != len(values):
        raise ActopoError(f"simplified/{name}{ORDER_SUFFIX}: {len(order)} values, expected "
                          f"{len(values)}")
    return SimplifiedField(name=name, values=values, order=order)
