"""The caller's arguments checked and turned into parts of messages: ids, simplices, names,
partitions and engine counts (no I/O). _messages builds the requests from them."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Literal, Protocol, TypeAlias, TypedDict

import numpy as np
import numpy.typing as npt

from actopo import _names
from actopo._arrays import little_endian, to_array
from actopo._errors import InvalidArgumentError
from actopo._literals import Relation
from actopo._proto import pb
from actopo._types import MeshInfo

MeshRef: TypeAlias = MeshInfo | str
"""A mesh: its MeshInfo or its id."""
MeshSource: TypeAlias = str | Sequence[str]
"""What Client.load_mesh() loads: a path under the server's data directory, "sample:NAME", or
the paths of a series' files (a list)."""

Id: TypeAlias = int | np.integer[Any]
"""One simplex id, or one vertex id of a tuple."""
IdArray: TypeAlias = npt.NDArray[np.integer[Any]]
"""A numpy array of ids: 1-D ids, or (n, k) vertex tuples."""
SimplexArg: TypeAlias = Id | Sequence[Id] | IdArray
"""One simplex: its id, or its vertices (1 to 4 input vertex ids, any order)."""
SimplexIds: TypeAlias = Id | Sequence[Id] | Sequence[Sequence[Id]] | IdArray
"""Many simplices: one id, a sequence or 1-D array of ids, or (n, k) vertex tuples as nested
sequences or a 2-D array."""

FieldsArg: TypeAlias = Sequence[str] | Literal["all"] | None
"""The fields a job runs over: names, "all" (every floating-point field of the session's mesh,
in its order), or None for the session's scalar field alone."""

DEFAULT_BATCH = 100_000


class HasSessionId(Protocol):
    """A Session, an AsyncSession or a SessionInfo."""

    @property
    def session_id(self) -> str: ...


SessionRef: TypeAlias = str | HasSessionId


def mesh_id(mesh: MeshRef) -> str:
    return mesh.mesh_id if isinstance(mesh, MeshInfo) else str(mesh)


def session_id(session: SessionRef) -> str:
    return session if isinstance(session, str) else session.session_id


def partition(block_size: int = 0, block_label_field: str = "") -> pb.PartitionOptions:
    if block_size < 0:
        raise InvalidArgumentError(f"block_size: {block_size} is negative")
    return pb.PartitionOptions(block_size=block_size, block_label_field=block_label_field or "")


def file_series(paths: Sequence[str], times: Sequence[float] | None) -> pb.FileSeries:
    """A series' files (LoadMeshRequest.files): the paths in step order, and a time value per
    path, or none (the server then gives each file its index)."""
    names = list(paths)
    for k, name in enumerate(names):
        if not isinstance(name, str):
            raise InvalidArgumentError(f"path[{k}]: {name!r} is not a path (a string)")
    if times is None:
        return pb.FileSeries(paths=names)
    values = list(times)
    if len(values) != len(names):
        raise InvalidArgumentError(f"times: {len(values)} values for {len(names)} paths; give "
                                   "one per path, or none")
    for k, value in enumerate(values):
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer,
                                                             np.floating)):
            raise InvalidArgumentError(f"times[{k}]: {value!r} is not a number")
        if not math.isfinite(value):
            raise InvalidArgumentError(f"times[{k}]: {value} is not finite")
    return pb.FileSeries(paths=names, times=[float(v) for v in values])


def engine_count(what: str, value: int) -> int:
    """A thread or reader count of the engine options: an integer in [0, 2^31 - 1], 0 meaning
    the server's default (the server checks the range it allows, e.g. [1, 64])."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise InvalidArgumentError(f"engine.{what}: {value!r} is not an integer")
    if not 0 <= value <= 2**31 - 1:
        raise InvalidArgumentError(f"engine.{what}: {value} is negative or too large "
                                   "(0 means the server's default)")
    return int(value)


def relation(name: Relation) -> pb.Relation:
    """The enum value of a relation's name; an unknown name raises InvalidArgumentError."""
    return _names.lookup(_names.RELATIONS, name, "relation")


def simplex(value: SimplexArg) -> pb.Simplex:
    """An id (int) or a vertex tuple (sequence of 1 to 4 input vertex ids)."""
    if isinstance(value, (int, np.integer)):
        return pb.Simplex(id=int(value))
    ids = [int(v) for v in np.asarray(value).reshape(-1)]
    return pb.Simplex(vertices=pb.VertexTuple(ids=ids))


def simplex_array(ids: SimplexIds) -> np.ndarray:
    """`ids` as the service takes them: one id, 1-D ids, or an (n, k) array of vertex tuples;
    int32 stays int32, other integers become int64; little-endian and C-contiguous (no copy
    when they already are)."""
    values = np.asarray(ids)
    if values.ndim == 0:
        values = values.reshape(1)
    if values.size and values.dtype.kind not in "iu":
        raise InvalidArgumentError(f"ids: must be integers, got dtype {values.dtype}")
    if values.ndim not in (1, 2):
        raise InvalidArgumentError(f"ids: must be 1-D ids or (n, k) vertex tuples, got shape "
                                   f"{values.shape}")
    int32 = values.dtype.kind == "i" and values.dtype.itemsize == 4
    return little_endian(values, np.int32 if int32 else np.int64)


class SimplexArrays(TypedDict, total=False):
    """The keyword arguments of a batch request that carry its simplices: one of the two."""

    ids: pb.Array
    vertex_tuples: pb.Array


def simplices(values: np.ndarray) -> SimplexArrays:
    """The ``ids`` (1-D) or ``vertex_tuples`` (2-D) field of a batch request."""
    if values.ndim == 1:
        return {"ids": to_array(values, "ids")}
    return {"vertex_tuples": to_array(values, "vertex_tuples")}


class JobFields(TypedDict, total=False):
    """The keyword arguments of a RunJobRequest that name its fields: one of the two, or none."""

    fields: list[str]
    all_fields: bool


def job_fields(fields: FieldsArg) -> JobFields:
    """The ``fields`` or ``all_fields`` of a job's request; {} for a job on the session's
    scalar field."""
    if fields is None:
        return {}
    if isinstance(fields, str):
        if fields == "all":
            return {"all_fields": True}
        raise InvalidArgumentError(f"fields: '{fields}' is neither a list of field names nor "
                                   f"'all' (for that field alone: ['{fields}'])")
    names = list(fields)
    if not names:
        raise InvalidArgumentError("fields: an empty list; give field names, or 'all'")
    for name in names:
        if not isinstance(name, str):
            raise InvalidArgumentError(f"fields: {name!r} is not a field name")
    return {"fields": names}


def download_fields(fields: FieldsArg) -> JobFields:
    """The ``fields`` or ``all_fields`` of a DownloadMeshRequest: names, or "all" (every point
    field, integer ones too); {} for none (None or an empty list)."""
    if fields is None or (not isinstance(fields, str) and len(fields) == 0):
        return {}
    return job_fields(fields)


def _number(what: str, value: float) -> str:
    """A number parameter as the server reads it (the shortest text that round-trips)."""
    if isinstance(value, bool):
        raise InvalidArgumentError(f"{what}: {value!r} is not a number")
    try:
        return repr(float(value))
    except (TypeError, ValueError):
        raise InvalidArgumentError(f"{what}: {value!r} is not a number") from None


def distance_parameters(p: float, persistence_threshold: float | None,
                        relative_threshold: float | None, essential: bool) -> dict[str, str]:
    """The parameters of a diagram-distance job (the server checks their values and that at
    most one threshold is given)."""
    parameters = {"p": _number("p", p), "essential": "true" if essential else "false"}
    if persistence_threshold is not None:
        parameters["persistence_threshold"] = _number("persistence_threshold",
                                                      persistence_threshold)
    if relative_threshold is not None:
        parameters["relative_threshold"] = _number("relative_threshold", relative_threshold)
    return parameters
