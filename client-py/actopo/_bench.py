"""Load on a running server, for `actopo bench`: N concurrent clients (threads, each with a
channel of its own) asking one relation through GetRelation ("unary"), GetRelationBatch
("batch") or StreamRelations batches ("stream"), or running jobs ("job"), for a duration or a
number of requests; with the server's own account of the time from GetSessionStats."""

from __future__ import annotations

import contextlib
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from actopo import _names, _requests
from actopo._client import Client, Session
from actopo._errors import ActopoError, InvalidArgumentError
from actopo._literals import Algorithm, Relation, Structure
from actopo._types import FailedItem, MeshInfo, SessionStats

MODES = ("unary", "batch", "stream", "job")
ORDERS = ("sequential", "random")
_SOURCES = {"vertex": "vertices", "edge": "edges", "triangle": "triangles",
            "tetrahedron": "tetrahedra"}
_PERCENTILES = {"p50": 50.0, "p90": 90.0, "p99": 99.0, "p99.9": 99.9}


@dataclass(frozen=True)
class Load:
    """What every client of a mode does.

    seconds: how long each mode runs, unless `requests` (per client) is set.
    batch_size: simplices per GetRelationBatch call; stream_size: simplices per streamed array
    (one RelationBatch each, cut into messages of `chunk_size`), `window` messages in flight.
    """

    relation: Relation
    seconds: float = 5.0
    requests: int = 0
    batch_size: int = 4096
    stream_size: int = 65_536
    chunk_size: int | None = None
    window: int = 4
    order: str = "sequential"
    algorithm: Algorithm = "critical-points"
    parameters: dict[str, str] = field(default_factory=dict)


def source_count(mesh: MeshInfo, relation: Relation) -> int:
    """How many simplices the relation can be asked about (its source dimension's count)."""
    name = _names.name_of(_names.RELATIONS, _requests.relation(relation))
    return int(getattr(mesh, _SOURCES[name.split("_", 1)[0]]))


class _Ids:
    """The ids one client asks about: in order from `start` (wrapping), or at random."""

    def __init__(self, count: int, start: int, order: str, seed: int) -> None:
        self._count = max(count, 1)
        self._next = start % self._count
        self._random = np.random.default_rng(seed) if order == "random" else None

    def take(self, n: int) -> np.ndarray:
        """The next `n` ids as int32 (int64 past 2^31 simplices)."""
        dtype = np.int32 if self._count < 2**31 else np.int64
        if self._random is not None:
            return self._random.integers(0, self._count, n, dtype=dtype)
        ids = (self._next + np.arange(n, dtype=np.int64)) % self._count
        self._next = int(ids[-1] + 1) % self._count if n else self._next
        return ids.astype(dtype)


class _Tally:
    """What one client measured."""

    def __init__(self) -> None:
        self.requests = 0
        self.simplices = 0
        self.errors = 0
        self.latencies: list[float] = []
        self.run_seconds: list[float] = []
        self.first_error: str | None = None

    def done(self, seconds: float, simplices: int,
             errors: Sequence[FailedItem] = ()) -> None:
        """An answered request: its latency, the simplices answered and the items failed."""
        self.requests += 1
        self.simplices += simplices
        self.latencies.append(seconds)
        if errors:
            self.errors += len(errors)
            self.first_error = self.first_error or errors[0].message

    def fail(self, error: Exception) -> None:
        self.requests += 1
        self.errors += 1
        self.first_error = self.first_error or str(error)


class _Clock:
    """When the clients stop: `seconds` after go(), or after `requests` each; or at stop."""

    def __init__(self, load: Load) -> None:
        self._seconds = load.seconds
        self._requests = load.requests
        self.deadline = float("inf")
        self.started = threading.Event()
        self.stopped = threading.Event()

    def go(self) -> float:
        """Starts the clients; returns the start time."""
        now = time.perf_counter()
        if not self._requests:
            self.deadline = now + self._seconds
        self.started.set()
        return now

    def more(self, issued: int) -> bool:
        """Whether a client that issued `issued` requests issues another."""
        if self.stopped.is_set():
            return False
        if self._requests:
            return issued < self._requests
        return time.perf_counter() < self.deadline


def _unary(session: Session, load: Load, ids: _Ids, tally: _Tally, clock: _Clock) -> None:
    while clock.more(tally.requests):
        simplex = int(ids.take(1)[0])
        start = time.perf_counter()
        try:
            session.query(load.relation, simplex)
        except ActopoError as e:
            tally.fail(e)
            continue
        tally.done(time.perf_counter() - start, 1)


def _batch(session: Session, load: Load, ids: _Ids, tally: _Tally, clock: _Clock) -> None:
    code = _requests.relation(load.relation)
    while clock.more(tally.requests):
        values = _requests.simplex_array(ids.take(load.batch_size))
        start = time.perf_counter()
        try:
            session._batch(code, values)  # one GetRelationBatch call, whatever its size
        except ActopoError as e:
            tally.fail(e)
            continue
        tally.done(time.perf_counter() - start, len(values))


def _stream(session: Session, load: Load, ids: _Ids, tally: _Tally, clock: _Clock) -> None:
    """One StreamRelations call of `stream_size` arrays (a new one after an error); latency:
    from the array's sending to its RelationBatch."""
    issued = 0
    while clock.more(issued):
        sent: deque[float] = deque()

        def arrays(sent: deque[float]) -> Iterator[np.ndarray]:
            nonlocal issued
            while clock.more(issued):  # read by gRPC's sending thread
                values = ids.take(load.stream_size)
                issued += 1
                sent.append(time.perf_counter())
                yield values

        try:
            for batch in session.relation_batches(load.relation, arrays(sent),
                                                  chunk_size=load.chunk_size,
                                                  window=load.window):
                tally.done(time.perf_counter() - sent.popleft(),
                           batch.num_simplices - len(batch.errors), batch.errors)
        except ActopoError as e:
            tally.fail(e)


def _job(session: Session, load: Load, ids: _Ids, tally: _Tally, clock: _Clock) -> None:
    while clock.more(tally.requests):
        start = time.perf_counter()
        try:
            result = session.run(load.algorithm, parameters=load.parameters,
                                 include_arrays=False)
        except ActopoError as e:
            tally.fail(e)
            continue
        tally.done(time.perf_counter() - start, 0)
        if result.stats is not None:
            tally.run_seconds.append(result.stats.run_seconds)


_LOOPS: dict[str, Callable[[Session, Load, _Ids, _Tally, _Clock], None]] = {
    "unary": _unary, "batch": _batch, "stream": _stream, "job": _job}


def _percentiles(seconds: list[float]) -> dict[str, float | None]:
    if not seconds:
        return {**{k: None for k in _PERCENTILES}, "mean": None, "max": None}
    ms = np.asarray(seconds) * 1e3
    values = np.percentile(ms, list(_PERCENTILES.values()))
    return {**{k: float(v) for k, v in zip(_PERCENTILES, values, strict=True)},
            "mean": float(ms.mean()), "max": float(ms.max())}


def _server_queries(before: SessionStats, after: SessionStats) -> dict[str, Any]:
    """The server's account of the relation calls between two snapshots of a session."""
    calls = after.relation_queries.count - before.relation_queries.count
    b0, b1 = before.query_breakdown, after.query_breakdown
    breakdown = {"simplices": b1.simplices - b0.simplices, "queue_ns": b1.queue_ns - b0.queue_ns,
                 "compute_ns": b1.compute_ns - b0.compute_ns,
                 "serialize_ns": b1.serialize_ns - b0.serialize_ns}
    parts = ("queue", "compute", "serialize")
    simplices = breakdown["simplices"]
    return {
        "relation_queries": {"count": calls,
                             "ns": after.relation_queries.ns - before.relation_queries.ns},
        "query_breakdown": breakdown,
        "per_simplex_ns": {p: breakdown[f"{p}_ns"] / simplices if simplices else None
                           for p in parts},
        "per_call_us": {p: breakdown[f"{p}_ns"] / calls / 1e3 if calls else None
                        for p in parts},
        "engine": {"requests": after.engine.requests - before.engine.requests,
                   "misses": after.engine.misses - before.engine.misses,
                   "wait_ns": after.engine.wait_ns - before.engine.wait_ns},
    }


def _server_jobs(before: list[SessionStats], after: list[SessionStats],
                 run_seconds: list[float]) -> dict[str, Any]:
    pairs = list(zip(after, before, strict=True))
    return {"jobs": {"count": sum(a.jobs.count - b.jobs.count for a, b in pairs),
                     "ns": sum(a.jobs.ns - b.jobs.ns for a, b in pairs)},
            "run_s": _percentiles(run_seconds) if run_seconds else None}


class Bench:
    """Runs the modes against one mesh.

    `connect`: makes a Client with a channel of its own (same target, credentials and affinity
    key as the caller's); `open_session(client, structure)`: opens a session with the engine
    options asked for.
    """

    def __init__(self, connect: Callable[[], Client],
                 open_session: Callable[[Client, Structure], Session], mesh: MeshInfo,
                 load: Load) -> None:
        if load.seconds <= 0 and not load.requests:
            raise InvalidArgumentError("duration: must be positive (or give a request count)")
        self._connect = connect
        self._open = open_session
        self._mesh = mesh
        self._load = load
        self._count = source_count(mesh, load.relation)

    def run(self, structure: Structure, mode: str, clients: int,
            shared: Session | None) -> dict[str, Any]:
        """One mode with `clients` clients. Relation modes ask `shared` (a session of the
        caller's); jobs run on a session per client (a session runs one job at a time)."""
        if clients < 1:
            raise InvalidArgumentError(f"clients: {clients} is not positive")
        if mode != "job" and shared is None:
            raise ValueError(f"bench: the {mode} mode needs a session")
        with contextlib.ExitStack() as stack:
            handles = []
            for _ in range(clients):
                client = stack.enter_context(self._connect())
                if shared is None or mode == "job":
                    handles.append(stack.enter_context(self._open(client, structure)))
                else:
                    handles.append(Session(client, shared.info))
            watched = handles if shared is None or mode == "job" else [shared]
            before = [s.stats() for s in watched]
            tallies, seconds = self._drive(mode, handles)
            after = [s.stats() for s in watched]
            readers = watched[0].info.engine.query_readers
        return self._row(structure, mode, clients, readers, tallies, seconds, before, after)

    def _drive(self, mode: str, sessions: list[Session]) -> tuple[list[_Tally], float]:
        """Runs one client per session, all started at once; returns their tallies and the
        wall time from the start to the last one's end."""
        clock = _Clock(self._load)
        tallies = [_Tally() for _ in sessions]
        step = self._count // len(sessions)
        threads = []
        for i, (session, tally) in enumerate(zip(sessions, tallies, strict=True)):
            ids = _Ids(self._count, i * step, self._load.order, seed=i)
            threads.append(threading.Thread(target=self._client, daemon=True,
                                            args=(_LOOPS[mode], session, ids, tally, clock)))
        for t in threads:
            t.start()
        start = clock.go()
        try:
            for t in threads:
                while t.is_alive():
                    t.join(0.1)
        except KeyboardInterrupt:
            clock.stopped.set()
            raise
        return tallies, time.perf_counter() - start

    def _client(self, loop: Callable[[Session, Load, _Ids, _Tally, _Clock], None],
                session: Session, ids: _Ids, tally: _Tally, clock: _Clock) -> None:
        clock.started.wait()
        try:
            loop(session, self._load, ids, tally, clock)
        except Exception as e:
            tally.fail(e)

    def _row(self, structure: str, mode: str, clients: int, readers: int,
             tallies: list[_Tally], seconds: float, before: list[SessionStats],
             after: list[SessionStats]) -> dict[str, Any]:
        requests = sum(t.requests for t in tallies)
        simplices = sum(t.simplices for t in tallies)
        latencies = [x for t in tallies for x in t.latencies]
        errors = [t.first_error for t in tallies if t.first_error]
        if mode == "job":
            server = _server_jobs(before, after, [x for t in tallies for x in t.run_seconds])
        else:
            server = _server_queries(before[0], after[0])
        return {
            "structure": structure, "mode": mode, "clients": clients,
            "query_readers": readers, "requests": requests,
            "simplices": simplices if mode != "job" else None,
            "errors": sum(t.errors for t in tallies), "seconds": seconds,
            "requests_per_s": requests / seconds if seconds > 0 else 0.0,
            "simplices_per_s": (simplices / seconds if seconds > 0 else 0.0)
            if mode != "job" else None,
            "latency_ms": _percentiles(latencies),
            "server": server,
            "first_error": errors[0] if errors else None,
        }
