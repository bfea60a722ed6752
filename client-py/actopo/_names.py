"""Names users write for the API's enums: "vertex_edges", "morse-smale", "actopo", ..."""

from __future__ import annotations

from typing import Any, TypeVar

from actopo._errors import InvalidArgumentError
from actopo._proto import pb

_E = TypeVar("_E", bound=int)


def _names(enum: Any, prefix: str, sep: str = "_") -> dict[str, Any]:
    """The values of a proto enum by lower-case name without `prefix` (UNSPECIFIED left out).
    The enum's values are of the enum's type; protoc's .pyi types them as int, so each table
    below says which enum it holds."""
    values: list[tuple[str, int]] = enum.items()
    return {name[len(prefix):].lower().replace("_", sep): value
            for name, value in values if not name.endswith("_UNSPECIFIED")}


RELATIONS: dict[str, pb.Relation] = _names(pb.Relation, "RELATION_")
ALGORITHMS: dict[str, pb.Algorithm] = _names(pb.Algorithm, "ALGORITHM_", "-")
STRUCTURES: dict[str, pb.Structure] = _names(pb.Structure, "STRUCTURE_")
PREFETCH: dict[str, pb.Prefetch] = {
    "auto": pb.PREFETCH_UNSPECIFIED, **_names(pb.Prefetch, "PREFETCH_")}
PRECOMPUTE: dict[str, pb.Precompute] = {
    "auto": pb.PRECOMPUTE_UNSPECIFIED, **_names(pb.Precompute, "PRECOMPUTE_")}


def lookup(table: dict[str, _E], name: str, what: str) -> _E:
    """The enum value of `name`; '-' and '_' are interchangeable, case is ignored."""
    key = str(name).strip().lower()
    for candidate in (key, key.replace("-", "_"), key.replace("_", "-")):
        if candidate in table:
            return table[candidate]
    raise InvalidArgumentError(f"{what}: unknown {what} '{name}'; available: "
                               f"{', '.join(table)}")


def name_of(table: dict[str, _E], value: int, unspecified: str = "") -> str:
    for name, v in table.items():
        if v == value:
            return name
    return unspecified

