"""Server messages to the public result types."""

from __future__ import annotations

import dataclasses
import math
from datetime import datetime, timezone
from typing import TYPE_CHECKING, Any, TypeVar, cast

from google.protobuf import struct_pb2

from actopo import _names
from actopo._arrays import dtype_name
from actopo._literals import Precompute, Prefetch, Structure
from actopo._proto import pb
from actopo._types import (
    Counter,
    EngineOptions,
    EngineStats,
    FieldInfo,
    JobStats,
    LoadProgress,
    MemoryStats,
    MeshInfo,
    QueryBreakdown,
    ServerInfo,
    ServerLimits,
    SessionInfo,
    SessionStats,
)

if TYPE_CHECKING:
    from _typeshed import DataclassInstance

_D = TypeVar("_D", bound="DataclassInstance")


def _time(message: Any, name: str) -> datetime | None:
    if not message.HasField(name):
        return None
    stamp = getattr(message, name)
    return datetime.fromtimestamp(stamp.seconds + stamp.nanos / 1e9, tz=timezone.utc)


def _fields(message: Any, cls: type[_D]) -> _D:
    """The dataclass `cls` with each of its fields read from the message field of that name."""
    return cls(**{f.name: getattr(message, f.name) for f in dataclasses.fields(cls)})


def server_info(r: pb.GetServerInfoResponse) -> ServerInfo:
    return ServerInfo(version=r.version, library_versions=dict(r.library_versions),
                      algorithms=list(r.algorithms), relations=list(r.relations),
                      samples=list(r.samples), limits=_fields(r.limits, ServerLimits))


def mesh_info(m: pb.MeshInfo) -> MeshInfo:
    fields = [FieldInfo(name=f.name, dtype=dtype_name(f.dtype), min=f.min, max=f.max,
                        time=f.time if f.HasField("time") else None) for f in m.fields]
    return MeshInfo(mesh_id=m.mesh_id, name=m.name, source=m.source, vertices=m.vertices,
                    edges=m.edges if m.HasField("edges") else None,
                    triangles=m.triangles if m.HasField("triangles") else None,
                    tetrahedra=m.tetrahedra,
                    blocks=m.blocks, block_size=m.block_size, fields=fields, bytes=m.bytes,
                    sessions=m.sessions, created=_time(m, "created"),
                    load_seconds=m.load_seconds, partition_seconds=m.partition_seconds)


def load_progress(p: pb.LoadProgress) -> LoadProgress:
    return LoadProgress(phase=p.phase, fraction=p.fraction, elapsed_seconds=p.elapsed_seconds)


def session_info(s: pb.SessionInfo) -> SessionInfo:
    e = s.engine
    prefetch = cast(Prefetch, _names.name_of(_names.PREFETCH, e.prefetch, "auto"))
    precompute = cast(Precompute, _names.name_of(_names.PRECOMPUTE, e.precompute, "auto"))
    structure = cast(Structure, _names.name_of(_names.STRUCTURES, s.structure, "actopo"))
    engine = EngineOptions(consumers=e.consumers, producers=e.producers,
                           buffer_ratio=e.buffer_ratio, prefetch=prefetch, precompute=precompute,
                           query_readers=e.query_readers)
    return SessionInfo(session_id=s.session_id, mesh_id=s.mesh_id, scalar_field=s.scalar_field,
                       structure=structure, engine=engine, created=_time(s, "created"),
                       last_used=_time(s, "last_used"),
                       running_job_id=s.running_job_id or None)


def engine_stats(e: pb.EngineStats) -> EngineStats:
    return _fields(e, EngineStats)


def memory_stats(m: pb.MemoryStats) -> MemoryStats:
    return _fields(m, MemoryStats)


def session_stats(r: pb.GetSessionStatsResponse) -> SessionStats:
    return SessionStats(engine=engine_stats(r.engine), memory=memory_stats(r.memory),
                        relation_queries=_fields(r.relation_queries, Counter),
                        jobs=_fields(r.jobs, Counter), preprocess_seconds=r.preprocess_seconds,
                        query_breakdown=_fields(r.query_breakdown, QueryBreakdown))


def job_stats(s: pb.JobStats) -> JobStats:
    return JobStats(run_seconds=s.run_seconds, engine=engine_stats(s.engine),
                    memory=memory_stats(s.memory), faces_seconds=s.faces_seconds)


def struct_to_dict(struct: struct_pb2.Struct) -> dict[str, Any]:
    """A google.protobuf.Struct as plain Python, integral numbers as int.

    Struct numbers are doubles; the summaries hold counts (exact below 2**53) and hex digests,
    so ints come back as ints and the object equals actopo-bench's JSON `result`. A Struct is a
    map, whose order the wire does not keep: keys come back sorted. Non-finite numbers (an
    infinite distance) stay floats, inf or nan, where JSON has no spelling for them.
    """
    return {key: _value(struct.fields[key]) for key in sorted(struct.fields)}


def _value(value: struct_pb2.Value) -> Any:
    kind = value.WhichOneof("kind")
    if kind == "number_value":
        number = value.number_value
        if math.isfinite(number) and number.is_integer() and abs(number) < 2**53:
            return int(number)
        return number
    if kind == "struct_value":
        return struct_to_dict(value.struct_value)
    if kind == "list_value":
        return [_value(v) for v in value.list_value.values]
    if kind == "string_value":
        return value.string_value
    if kind == "bool_value":
        return value.bool_value
    return None
