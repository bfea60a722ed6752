"""Point fields to add to a loaded mesh (Client.add_fields): the caller's values checked and
turned into the little-endian arrays that AddFields sends.

Accepted: a mapping name -> values, or a pyvista dataset or a meshio.Mesh, whose scalar point
fields are taken (vector fields left out, as uploads leave them). float32 values travel as
FLOAT32 and float64 as FLOAT64; integers are converted to float64. Any other dtype, a shape
other than (n,) or (n, 1), or a length other than the mesh's vertex count raises
InvalidArgumentError here, naming the field, before anything is sent. What only the server
decides (an empty or taken name, non-finite values, the memory budget) comes back as its error.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeAlias

import numpy as np

from actopo._errors import InvalidArgumentError
from actopo._mesh import read_file

FieldsLike: TypeAlias = Any
"""Mapping[str, array-like] | pyvista dataset | meshio.Mesh."""
TimesArg: TypeAlias = Mapping[str, float] | Sequence[float] | None
"""The time value of each field added: by name, or one per field in order; None for none."""


@dataclass(frozen=True)
class FieldArray:
    """One field to add: its name, its values ((n,) '<f4' or '<f8', C-contiguous) and its time
    value, if any."""

    name: str
    values: np.ndarray
    time: float | None = None


def _is_meshio(data: Any) -> bool:
    return (hasattr(data, "cells") and hasattr(data, "point_data") and hasattr(data, "points")
            and isinstance(data.cells, list))


def _is_pyvista(data: Any) -> bool:
    return hasattr(data, "point_data") and hasattr(data, "n_points")


def _scalar(values: Any) -> bool:
    """Whether a dataset's point array is a scalar field of numbers (vectors, strings and
    booleans are not)."""
    array = np.asarray(values)
    return (array.ndim == 1 or (array.ndim == 2 and array.shape[1] == 1)) \
        and array.dtype.kind in "fiu"


def point_fields(data: Any) -> dict[str, np.ndarray]:
    """The scalar point fields of a pyvista dataset or a meshio.Mesh, by name, in the
    dataset's order."""
    if _is_meshio(data):
        arrays = {str(k): np.asarray(v) for k, v in data.point_data.items()}
    elif _is_pyvista(data):
        arrays = {str(k): np.asarray(data.point_data[k])
                  for k in data.point_data.keys()}  # noqa: SIM118 (pyvista)
    else:
        raise InvalidArgumentError(
            f"fields: cannot take point fields from a {type(data).__name__}: pass a mapping "
            "name -> values, a pyvista dataset or a meshio.Mesh")
    return {k: v for k, v in arrays.items() if _scalar(v)}


def read_point_fields(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
    """The scalar point fields of a local mesh file, read with pyvista, else meshio (as
    uploads read files)."""
    return point_fields(read_file(Path(path)))


def _values(name: str, raw: Any, vertices: int) -> np.ndarray:
    """One field's values as they travel: float32 or float64, little-endian, one per vertex."""
    values = np.asarray(raw)
    if values.ndim == 2 and values.shape[1] == 1:
        values = values[:, 0]
    kind, size = values.dtype.kind, values.dtype.itemsize
    if kind == "f" and size in (4, 8):
        dtype = np.dtype(f"<f{size}")
    elif kind in "iu":
        dtype = np.dtype("<f8")
    else:
        raise InvalidArgumentError(f"field '{name}': values must be float32, float64 or "
                                   f"integers, got dtype {values.dtype}")
    if values.ndim != 1:
        raise InvalidArgumentError(f"field '{name}': values must be one per vertex, shape "
                                   f"({vertices},), got shape {values.shape}")
    if len(values) != vertices:
        raise InvalidArgumentError(f"field '{name}': {len(values)} values, but the mesh has "
                                   f"{vertices} vertices")
    return np.ascontiguousarray(values, dtype=dtype)


def _times(names: Sequence[str], times: TimesArg) -> list[float | None]:
    """The time value of each field, in the fields' order."""
    if times is None:
        return [None] * len(names)
    if isinstance(times, Mapping):
        unknown = [str(k) for k in times if k not in names]
        if unknown:
            raise InvalidArgumentError(f"times: '{unknown[0]}' is not one of the fields added "
                                       f"({', '.join(names)})")
        given: list[Any] = [times.get(name) for name in names]
    else:
        given = list(times)
        if len(given) != len(names):
            raise InvalidArgumentError(f"times: {len(given)} values for {len(names)} fields")
    checked: list[float | None] = []
    for name, value in zip(names, given, strict=True):
        if value is not None:
            try:
                value = float(value)
            except (TypeError, ValueError):
                raise InvalidArgumentError(f"times['{name}']: {value!r} is not a number") \
                    from None
            if not math.isfinite(value):
                raise InvalidArgumentError(f"times['{name}']: {value} is not finite")
        checked.append(value)
    return checked


def field_arrays(fields: FieldsLike, vertices: int, times: TimesArg = None) -> list[FieldArray]:
    """The fields to add, checked against the mesh's vertex count, in the caller's order."""
    source = fields if isinstance(fields, Mapping) else point_fields(fields)
    if not source:
        raise InvalidArgumentError("fields: no field to add")
    for name in source:
        if not isinstance(name, str):
            raise InvalidArgumentError(f"fields: a field's name must be a string, got {name!r}")
    names = list(source)
    arrays = [_values(name, source[name], vertices) for name in names]
    return [FieldArray(name, values, time)
            for name, values, time in zip(names, arrays, _times(names, times), strict=True)]
