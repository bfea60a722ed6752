"""Requests and response merging shared by Client and AsyncClient (no I/O here)."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from typing import Any, TypeAlias, TypedDict, cast

import numpy as np

from actopo import _convert, _names
from actopo._arrays import little_endian, to_array, to_numpy
from actopo._errors import ActopoError, InvalidArgumentError
from actopo._literals import Algorithm, Precompute, Prefetch, Relation, Structure
from actopo._proto import pb
from actopo._types import LoadProgress, MeshInfo, RelationBatch, SimplexRelation

MeshRef: TypeAlias = MeshInfo | str
SimplexArg: TypeAlias = int | Sequence[int] | np.ndarray

DEFAULT_BATCH = 100_000


def mesh_id(mesh: MeshRef) -> str:
    return mesh.mesh_id if isinstance(mesh, MeshInfo) else str(mesh)


def session_id(session: Any) -> str:
    return str(getattr(session, "session_id", session))


def partition(block_size: int = 0, block_label_field: str = "") -> pb.PartitionOptions:
    if block_size < 0:
        raise InvalidArgumentError(f"block_size: {block_size} is negative")
    return pb.PartitionOptions(block_size=block_size, block_label_field=block_label_field or "")


def load(source: str, block_size: int = 0, block_label_field: str = "") -> pb.LoadMeshRequest:
    """`source`: a path under the server's data directory, or "sample:NAME"."""
    options = partition(block_size, block_label_field)
    if source.startswith("sample:"):
        return pb.LoadMeshRequest(sample=source[len("sample:"):], partition=options)
    return pb.LoadMeshRequest(path=source, partition=options)


class LoadStream:
    """Takes the answers of LoadMeshWithProgress: each progress message goes to `report` (which
    may raise, to stop the load), the mesh, which ends the stream, is kept for mesh()."""

    def __init__(self, report: Callable[[LoadProgress], Any]) -> None:
        self._report = report
        self._mesh: MeshInfo | None = None

    def feed(self, response: pb.LoadMeshWithProgressResponse) -> None:
        event = response.WhichOneof("event")
        if event == "progress":
            self._report(_convert.load_progress(response.progress))
        elif event == "mesh":
            self._mesh = _convert.mesh_info(response.mesh)

    def mesh(self) -> MeshInfo:
        if self._mesh is None:
            raise ActopoError("LoadMeshWithProgress: the stream ended without the mesh")
        return self._mesh


def engine_count(what: str, value: int) -> int:
    """A thread or reader count of the engine options: an integer in [0, 2^31 - 1], 0 meaning
    the server's default (the server checks the range it allows, e.g. [1, 64])."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise InvalidArgumentError(f"engine.{what}: {value!r} is not an integer")
    if not 0 <= value <= 2**31 - 1:
        raise InvalidArgumentError(f"engine.{what}: {value} is negative or too large "
                                   "(0 means the server's default)")
    return int(value)


def open_session(mesh: MeshRef, scalar: str | None, structure: Structure, consumers: int,
                 producers: int, buffer_ratio: float, prefetch: Prefetch,
                 precompute: Precompute, query_readers: int = 0) -> pb.OpenSessionRequest:
    engine = pb.EngineOptions(consumers=engine_count("consumers", consumers),
                              producers=engine_count("producers", producers),
                              buffer_ratio=buffer_ratio,
                              prefetch=_names.lookup(_names.PREFETCH, prefetch, "prefetch"),
                              precompute=_names.lookup(_names.PRECOMPUTE, precompute,
                                                       "precompute"),
                              query_readers=engine_count("query_readers", query_readers))
    return pb.OpenSessionRequest(
        mesh_id=mesh_id(mesh), scalar_field=scalar or "",
        structure=_names.lookup(_names.STRUCTURES, structure, "structure"), engine=engine)


def relation(name: Relation) -> Any:
    return _names.lookup(_names.RELATIONS, name, "relation")


def simplex(value: SimplexArg) -> pb.Simplex:
    """An id (int) or a vertex tuple (sequence of 1 to 4 input vertex ids)."""
    if isinstance(value, (int, np.integer)):
        return pb.Simplex(id=int(value))
    ids = [int(v) for v in np.asarray(value).reshape(-1)]
    return pb.Simplex(vertices=pb.VertexTuple(ids=ids))


def single(session: str, name: Relation, value: SimplexArg,
           include_vertices: bool) -> pb.GetRelationRequest:
    return pb.GetRelationRequest(session_id=session, relation=relation(name),
                                 simplex=simplex(value), include_vertices=include_vertices)


def single_result(r: pb.GetRelationResponse) -> SimplexRelation:
    ids = np.array(r.ids, dtype=np.int64)
    vertices = None
    if len(r.vertices):
        vertices = np.array(r.vertices, dtype=np.int64).reshape(len(ids), -1)
    return SimplexRelation(ids, vertices)


def simplex_array(ids: Any) -> np.ndarray:
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


def batches(session: str, name: Relation, ids: Any,
            max_batch: int) -> list[pb.GetRelationBatchRequest]:
    """GetRelationBatch requests of at most `max_batch` simplices each.

    `ids`: one id, a 1-D sequence of ids, or an (n, k) array of vertex tuples.
    """
    code = relation(name)
    values = simplex_array(ids)
    step = max(max_batch, 1)
    return [pb.GetRelationBatchRequest(session_id=session, relation=code,
                                       **simplices(values[start:start + step]))
            for start in range(0, max(len(values), 1), step)]


def merge(responses: Sequence[pb.GetRelationBatchResponse]) -> RelationBatch:
    """One CSR result from consecutive batch responses."""
    if len(responses) == 1:
        return RelationBatch(to_numpy(responses[0].offsets).astype(np.int64, copy=False),
                             to_numpy(responses[0].values).astype(np.int64, copy=False))
    offsets = [np.zeros(1, dtype=np.int64)]
    values = []
    total = 0
    for r in responses:
        o = to_numpy(r.offsets).astype(np.int64)
        offsets.append(o[1:] + total)
        total += int(o[-1]) if len(o) else 0
        values.append(to_numpy(r.values).astype(np.int64, copy=False))
    return RelationBatch(np.concatenate(offsets), np.concatenate(values))


def stream(session: str, name: Relation,
           simplices: Iterable[SimplexArg]) -> Iterator[pb.StreamRelationsRequest]:
    """One request per simplex; request_id is the simplex's index in the input.

    The relation is checked here, in the caller's thread: gRPC's sending thread, which takes
    the requests, would turn an error of its own into an UNKNOWN status without the message.
    """
    code = relation(name)
    return (pb.StreamRelationsRequest(request_id=index, session_id=session, relation=code,
                                      simplex=simplex(value))
            for index, value in enumerate(simplices))


def run(session: str, algorithm: Algorithm, parameters: Mapping[str, Any] | None,
        include_arrays: bool, trace: bool = False) -> tuple[pb.RunJobRequest, Algorithm]:
    code = _names.lookup(_names.ALGORITHMS, algorithm, "algorithm")
    request = pb.RunJobRequest(session_id=session, algorithm=code,
                               parameters={str(k): str(v) for k, v in (parameters or {}).items()},
                               include_arrays=include_arrays, trace=trace)
    return request, cast(Algorithm, _names.name_of(_names.ALGORITHMS, code))
