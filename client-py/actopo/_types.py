"""The result types: plain frozen dataclasses and named tuples, numpy arrays for bulk data."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from datetime import datetime
from typing import TYPE_CHECKING, Any, NamedTuple

import grpc
import numpy as np

from actopo._errors import ActopoError, error_for
from actopo._literals import Precompute, Prefetch, Structure

if TYPE_CHECKING:
    from typing_extensions import Self


@dataclass(frozen=True)
class ServerLimits:
    """Limits the server enforces (0 means unlimited or not reported)."""

    max_meshes: int = 0
    max_sessions: int = 0
    max_engine_threads: int = 0
    memory_budget_bytes: int = 0
    max_message_bytes: int = 0
    max_batch_size: int = 0
    session_idle_timeout_seconds: int = 0
    upload_budget_bytes: int = 0
    upload_timeout_seconds: int = 0
    max_uploads: int = 0


@dataclass(frozen=True)
class ServerInfo:
    """What a server offers: versions, algorithms, relations, samples and limits."""

    version: str
    library_versions: dict[str, str]
    algorithms: list[str]
    relations: list[str]
    samples: list[str]
    limits: ServerLimits


@dataclass(frozen=True)
class FieldInfo:
    """A point field of a mesh: name, numpy dtype name and value range, and the time value of
    a series member when it was added with one (Client.add_fields(..., times=...)), else
    None."""

    name: str
    dtype: str
    min: float
    max: float
    time: float | None = None


@dataclass(frozen=True)
class MeshInfo:
    """A mesh loaded on the server. Pass it (or its ``mesh_id``) to open_session().

    ``edges`` and ``triangles`` are None until the server has built them: it loads a mesh
    without them and builds them for the first job, relation query or explicit session that
    reads them (critical points never does), or for ``get_mesh(mesh, count_faces=True)``.
    """

    mesh_id: str
    name: str
    source: str
    vertices: int
    edges: int | None
    triangles: int | None
    tetrahedra: int
    blocks: int
    block_size: int
    fields: list[FieldInfo]
    bytes: int
    sessions: int
    created: datetime | None
    load_seconds: float
    partition_seconds: float


LOAD_PHASES = ("read", "partition", "encode")
"""The phases of a load, in the order the server goes through them."""

UPLOAD_PHASES = ("send", *LOAD_PHASES)
"""The phases of a file upload (upload_file()): the bytes sent, then the load's."""

JOB_PHASES = ("faces", "run")
"""The phases of a job: "faces" (the mesh's edges and triangles, built once per mesh by the first
job or query that reads them) when the algorithm reads them, then "run"."""


@dataclass(frozen=True)
class JobProgress:
    """How far a job has got: its phase (JOB_PHASES), the fraction of that phase done (0 to 1)
    and the seconds since the job started. A server that reports no phase runs the algorithm
    only: "run"."""

    phase: str
    fraction: float
    elapsed_seconds: float


@dataclass(frozen=True)
class LoadProgress:
    """How far a load has got (what a ``progress`` callable of load_mesh() receives).

    phase: "read" (the file or sample), "partition" (the octree) or "encode" (the static
    encoding), in that order, each reported at least once; for upload_file() "send" comes first
    (the file's bytes); fraction: how much of that phase is done, 0 to 1, not decreasing within
    the phase; elapsed_seconds: since the load (the upload) started; sent_bytes and
    total_bytes: in "send", the bytes the server holds or that are on their way, and the
    upload's size (None in the other phases).
    """

    phase: str
    fraction: float
    elapsed_seconds: float
    sent_bytes: int | None = None
    total_bytes: int | None = None


@dataclass(frozen=True)
class EngineOptions:
    """Engine configuration of a session as the server resolved it."""

    consumers: int
    producers: int
    buffer_ratio: float
    prefetch: Prefetch
    precompute: Precompute
    query_readers: int = 0
    """Relation calls the session answers at once (each with a reader of its own)."""


@dataclass(frozen=True)
class SessionInfo:
    """A session: a structure on a mesh and a scalar field."""

    session_id: str
    mesh_id: str
    scalar_field: str
    structure: Structure
    engine: EngineOptions
    created: datetime | None
    last_used: datetime | None
    running_job_id: str | None


@dataclass(frozen=True)
class Counter:
    """A cumulative counter: events and their total duration. Diff two snapshots for rates."""

    count: int = 0
    ns: int = 0

    @property
    def seconds(self) -> float:
        return self.ns / 1e9


@dataclass(frozen=True)
class EngineStats:
    """Access statistics of the structure: requests, hits, misses, wait, producers' work."""

    requests: int = 0
    hits: int = 0
    misses: int = 0
    evictions: int = 0
    wait_ns: int = 0
    leader_relations: int = 0
    worker_relations: int = 0
    consumer_relations: int = 0
    duplicates_avoided: int = 0
    producer_busy_ns: int = 0
    buffer_bytes: int = 0
    buffer_peak_bytes: int = 0
    # Misses a consumer computed itself after waiting for a starved idle-priority producer.
    waits_abandoned: int = 0

    @property
    def wait_seconds(self) -> float:
        """Time the consumers waited for relations."""
        return self.wait_ns / 1e9

    @property
    def hit_rate(self) -> float:
        """Fraction of block-level requests found ready (1.0 when there were none)."""
        return self.hits / self.requests if self.requests else 1.0


@dataclass(frozen=True)
class MemoryStats:
    """Memory of a session, in bytes."""

    static_bytes: int = 0
    relation_bytes: int = 0
    relation_peak_bytes: int = 0
    process_rss_bytes: int = 0


@dataclass(frozen=True)
class QueryBreakdown:
    """Server-side time of a session's relation calls (unary, batch and streamed), summed.

    ``simplices`` counts the simplices answered (a batch of n counts n, failed items not);
    ``queue_ns`` is the time calls waited for a free query reader, ``compute_ns`` the time spent
    reading or computing the rows, ``serialize_ns`` the time packing them into messages.
    """

    simplices: int = 0
    queue_ns: int = 0
    compute_ns: int = 0
    serialize_ns: int = 0

    @property
    def queue_seconds(self) -> float:
        return self.queue_ns / 1e9

    @property
    def compute_seconds(self) -> float:
        return self.compute_ns / 1e9

    @property
    def serialize_seconds(self) -> float:
        return self.serialize_ns / 1e9


@dataclass(frozen=True)
class SessionStats:
    """Cumulative statistics of a session (Session.stats())."""

    engine: EngineStats
    memory: MemoryStats
    relation_queries: Counter
    jobs: Counter
    preprocess_seconds: float
    query_breakdown: QueryBreakdown = field(default_factory=QueryBreakdown)


@dataclass(frozen=True)
class JobStats:
    """Timings and statistics of one job."""

    run_seconds: float
    engine: EngineStats
    memory: MemoryStats
    faces_seconds: float = 0.0
    """Before the run: building the mesh's edges and triangles, or waiting for their build (the
    first job on a mesh that reads them); 0 when they were there or the algorithm reads none."""


@dataclass(frozen=True)
class FailedItem:
    """A simplex of a batch that the server could not answer: its position in the input array,
    the gRPC status code and the server's message (naming the field and value)."""

    index: int
    code: grpc.StatusCode
    message: str

    @property
    def error(self) -> ActopoError:
        """The exception this failure raises (OutOfRangeError, NotFoundError, ...)."""
        return error_for(self.code, self.message)


class _CSR(NamedTuple):
    offsets: np.ndarray
    values: np.ndarray


class RelationBatch(_CSR):
    """A relation of many simplices in CSR form: the values of simplex i are
    ``values[offsets[i]:offsets[i + 1]]``. Unpacks as ``offsets, values = batch``.

    ``errors`` lists the simplices that failed, by position, when they were not raised
    (``raise_errors=False``); their rows are empty. It is an attribute, not part of the tuple.
    """

    errors: tuple[FailedItem, ...] = ()

    def __new__(cls, offsets: np.ndarray, values: np.ndarray,
                errors: Iterable[FailedItem] = ()) -> Self:
        batch = super().__new__(cls, offsets, values)
        failed = tuple(errors)
        if failed:
            batch.errors = failed
        return batch

    def __repr__(self) -> str:
        text = super().__repr__()
        return f"{text[:-1]}, errors={list(self.errors)!r})" if self.errors else text

    @property
    def num_simplices(self) -> int:
        """Number of simplices asked about."""
        return max(len(self.offsets) - 1, 0)

    def of(self, i: int) -> np.ndarray:
        """The values of the i-th simplex asked about."""
        return self.values[self.offsets[i]:self.offsets[i + 1]]

    def split(self) -> list[np.ndarray]:
        """One array per simplex."""
        return np.split(self.values, self.offsets[1:-1]) if self.num_simplices else []


class SimplexRelation(NamedTuple):
    """A relation of one simplex: result ids and, when asked, the vertices of each result
    edge or triangle as a (len(ids), k) array."""

    ids: np.ndarray
    vertices: np.ndarray | None


@dataclass(frozen=True)
class StreamItem:
    """One answer of Session.relations_stream(): the index of the simplex in the input, the
    result ids, or the error of this item (the stream goes on after an item error)."""

    index: int
    ids: np.ndarray
    error: ActopoError | None


def plain(value: Any) -> Any:
    """`value` with dataclasses, named tuples, numpy values and datetimes as JSON types."""
    if isinstance(value, tuple) and hasattr(value, "_asdict"):
        return {k: plain(v) for k, v in value._asdict().items()}
    if hasattr(value, "__dataclass_fields__"):
        return {k: plain(getattr(value, k)) for k in value.__dataclass_fields__}
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, datetime):
        return value.isoformat()
    if isinstance(value, ActopoError):
        return str(value)
    return value
