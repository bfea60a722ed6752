"""Names users write for the API's enums: "vertex_edges", "morse-smale", "actopo", ..."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from actopo._errors import InvalidArgumentError
from actopo._proto import pb


def _names(enum: Any, prefix: str, sep: str = "_") -> dict[str, Any]:
    values: Mapping[str, int] = dict(enum.items())
    return {name[len(prefix):].lower().replace("_", sep): value
            for name, value in values.items() if not name.endswith("_UNSPECIFIED")}


RELATIONS = _names(pb.Relation, "RELATION_")
ALGORITHMS = _names(pb.Algorithm, "ALGORITHM_", "-")
STRUCTURES = _names(pb.Structure, "STRUCTURE_")
PREFETCH = {"auto": pb.PREFETCH_UNSPECIFIED, **_names(pb.Prefetch, "PREFETCH_")}
PRECOMPUTE = {"auto": pb.PRECOMPUTE_UNSPECIFIED, **_names(pb.Precompute, "PRECOMPUTE_")}


def lookup(table: dict[str, Any], name: str, what: str) -> Any:
    """The enum value of `name`; '-' and '_' are interchangeable, case is ignored."""
    key = str(name).strip().lower()
    for candidate in (key, key.replace("-", "_"), key.replace("_", "-")):
        if candidate in table:
            return table[candidate]
    raise InvalidArgumentError(f"{what}: unknown {what} '{name}'; available: "
                               f"{', '.join(table)}")


def name_of(table: dict[str, Any], value: int, unspecified: str = "") -> str:
    for name, v in table.items():
        if v == value:
            return name
    return unspecified
