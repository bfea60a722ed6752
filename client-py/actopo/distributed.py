"""One series over several actopo-servers, with Dask distributed (the ``dask`` extra).

A server is one process on one machine. When the fields of a mesh (a time series, an ensemble)
are too many for one, run an actopo-server beside each Dask worker, on the same data, and let
Dask spread the fields over them. Dask does the scheduling; this module only says what each
worker does on its server.

    from dask.distributed import Client as DaskClient, LocalCluster
    from actopo.distributed import distance_matrix_distributed, run_distributed

    with LocalCluster(n_workers=2, threads_per_worker=1) as cluster, DaskClient(cluster) as dask:
        servers = ["127.0.0.1:50051", "127.0.0.1:50052"]  # to the workers sorted by address
        fields = [f"velocityMag_{t:02d}" for t in (2, 3, 4, 5, 30, 31, 32, 33)]
        results = run_distributed(dask, servers, "isabel_series_s2_tet.vtu",
                                  "persistence-diagram", fields, digests=True)
        matrix = distance_matrix_distributed(dask, servers, "isabel_series_s2_tet.vtu", fields)

`servers` maps each Dask worker address to the actopo-server co-located with it, or lists
server addresses, which go to the workers sorted by address. The mesh is a path under the
servers' data directory (or "sample:NAME"): the data are where the servers are, so every server
loads the mesh itself and nothing but results crosses the network. Each task connects with
``actopo.Client(server)``: plaintext, the client's default deadlines (30 s for quick calls,
600 s to load the mesh and open the session; a server that is down fails at once). Jobs have
no deadline unless `timeout` gives one. A failure raises the error of the server (same class
and code) with the server's address and the task's fields put first; the other tasks are
cancelled on the Dask side, but a job already running goes on until it ends on its server.

run_distributed. The fields are cut into contiguous chunks, one per worker (of sizes that
differ by one at most). Each worker loads the mesh on its server, opens one session, runs one
job over its chunk (Session.run with ``fields=chunk``), closes the session and deletes the
mesh. The per-field results come back in the order of `fields`: FieldResult is a plain
dataclass of numpy arrays and pickles as it is. Its ``index`` is the field's position in
`fields`, its ``job_id`` the job of the server that ran it.

distance_matrix_distributed. The entries must be the server's exact floats, so each is
computed by a diagram-distance job on a server that has both diagrams in that job. The server
computes entry (i, j), i before j in the job's list, from the two diagrams alone, whichever
other fields the job has (server/diagrams/distance.cc), so a job over a sub-list in the same
order gives bit for bit the entries of one job over all the fields. What the API does not
offer is a job over some entries only, or over diagrams computed elsewhere: a job over m
fields computes m diagrams and all m(m - 1)/2 entries between them. A cover of the matrix by
jobs therefore duplicates work, and the plan keeps that small:

- The n fields are cut into b contiguous chunks. One job per pair of chunks, over their union
  in the order of `fields`, gives the entries between the two chunks and, again, those within
  each: every entry is in some job, and the entries between chunks in exactly one. Running a
  job over a chunk alone as well would only repeat entries the pairs already give, so there
  is none.
- b is the smallest number of chunks whose b(b - 1) / 2 pairs give every worker a job
  (b = 2, one job over all the fields, for one worker; 3 for 2 or 3 workers, 4 for 4 to 6,
  5 for 7 to 10), and at most n: every extra chunk means
  each field's diagram once more. The jobs go to the workers largest first, each to the
  worker with the fewest entries so far; a worker runs its jobs one after the other on one
  session, the mesh loaded once.
- Cost: over all servers, each diagram is computed b - 1 times (one server: once), and the
  entries within a chunk b - 1 times, those between chunks once. A job has about 2n/b fields,
  so a server computes about 2n/b diagrams and (2n/b)^2 / 2 entries per job it runs. With
  w = b(b - 1) / 2 workers (3, 6, 10, ...) each runs one job: about n^2 / w entries (one
  server: n^2 / 2) and 2n/b diagrams (one server: n). Two workers get b = 3: one runs two jobs
  (4n/3 diagrams, 4n^2/9 entries), the other one job (2n/3 diagrams, 2n^2/9 entries); on the
  12 Isabel fields that is 16 and 8 diagrams and 56 and 28 of the 66 entries. So two servers
  barely beat one: spread a matrix over three servers or more, where the distances, which grow
  as n^2, dominate.

The entries that several jobs compute are compared, and the pairs and thresholds of each
field: a difference (servers of different versions) raises ActopoError naming the fields and
the servers, rather than a matrix that one server would not give.
"""

from __future__ import annotations

import contextlib
import dataclasses
import itertools
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, TypeAlias, TypeVar

import numpy as np

try:
    import distributed
except ImportError as e:  # pragma: no cover - the extra is installed wherever this is tested
    raise ImportError("actopo.distributed needs Dask distributed: "
                      "pip install 'actopo[dask]'") from e

from actopo import _names
from actopo._client import Client, Session
from actopo._distances import DistanceMatrix
from actopo._errors import ActopoError, InvalidArgumentError, NotFoundError
from actopo._literals import Algorithm, Structure
from actopo._proto import pb
from actopo._requests import distance_parameters
from actopo._results import FieldResult, distance_matrix_of
from actopo._types import MeshInfo

__all__ = ["Servers", "distance_matrix_distributed", "run_distributed"]

Servers: TypeAlias = Mapping[str, str] | Sequence[str]
"""Dask worker address -> the "HOST:PORT" of the actopo-server beside it, the fields' chunks
going to the workers in this order; or server addresses, given to the workers sorted by address
(a list may be shorter than the workers, not longer)."""


def run_distributed(dask_client: distributed.Client, servers: Servers, mesh: str,
                    algorithm: Algorithm, fields: Sequence[str], *,
                    structure: Structure = "actopo", parameters: Mapping[str, Any] | None = None,
                    digests: bool = False, include_arrays: bool = False,
                    timeout: float | None = None) -> list[FieldResult]:
    """Runs `algorithm` over `fields` of `mesh`, each worker over a contiguous chunk of them on
    its server, and returns the FieldResult of each field in the order of `fields`.

    `mesh`: a path under the servers' data directory, or "sample:NAME"; each server loads it.
    `algorithm`, `structure`, `parameters`, `digests`, `include_arrays`: as for Session.run()
    (arrays are off by default: they travel from each server through its worker to here);
    diagram-distance and tracking compare fields across chunks, so they are refused (see
    distance_matrix_distributed()). `timeout`: each job's deadline in seconds (None: none).

    Each worker loads the mesh once, opens one session, runs one job over its chunk, closes the
    session and deletes the mesh. A field unknown to the mesh raises NotFoundError naming it
    and the server; a server that cannot be reached, UnavailableError naming it.
    """
    names = _field_names(fields, at_least=1)
    code = _names.lookup(_names.ALGORITHMS, algorithm, "algorithm")
    if code in (pb.ALGORITHM_DIAGRAM_DISTANCE, pb.ALGORITHM_TRACKING):
        raise InvalidArgumentError(
            f"algorithm: '{algorithm}' compares fields with each other, which chunks of them "
            "cannot; for diagram-distance use distance_matrix_distributed()")
    _names.lookup(_names.STRUCTURES, structure, "structure")
    places = _places(dask_client, servers)[:len(names)]
    tasks = [_ChunkRun(place, mesh, structure, [(i, names[i]) for i in chunk], algorithm,
                       dict(parameters or {}), digests, include_arrays, timeout)
             for place, chunk in zip(places, _chunks(len(names), len(places)), strict=True)]
    chunks: list[list[FieldResult]] = _gather(dask_client, tasks, _run_chunk)
    results = [result for chunk in chunks for result in chunk]
    if [r.field for r in results] != names:
        raise ActopoError(f"run_distributed: the results are of {[r.field for r in results]}, "
                          f"not of {names}")
    return results


def distance_matrix_distributed(dask_client: distributed.Client, servers: Servers, mesh: str,
                                fields: Sequence[str], *, p: float = 2,
                                persistence_threshold: float | None = None,
                                relative_threshold: float | None = None,
                                essential: bool = False, structure: Structure = "actopo",
                                timeout: float | None = None) -> DistanceMatrix:
    """The distances between the persistence diagrams of `fields` (at least two), computed by
    diagram-distance jobs on several servers and equal, float for float, to one server's
    Session.distance_matrix(fields, ...).

    The fields are cut into contiguous chunks, a job runs over each pair of chunks, and the
    jobs are spread over the workers (the module's docstring says how many and what they
    cost). Each worker loads the mesh once, opens one session, runs its jobs one after the
    other, closes the session and deletes the mesh. `p`, `persistence_threshold`,
    `relative_threshold` and `essential` are Session.distance_matrix()'s; `structure` and
    `timeout` as for run_distributed().
    """
    names = _field_names(fields, at_least=2)
    parameters = distance_parameters(p, persistence_threshold, relative_threshold, essential)
    _names.lookup(_names.STRUCTURES, structure, "structure")
    places = _places(dask_client, servers)
    plan = _distance_plan(len(names), len(places))
    tasks = [_DistanceJobs(place, mesh, structure,
                           [(i, names[i]) for i in sorted({i for job in jobs for i in job})],
                           [[names[i] for i in job] for job in jobs], parameters, timeout)
             for place, jobs in zip(places, plan, strict=True) if jobs]
    matrices: list[list[DistanceMatrix]] = _gather(dask_client, tasks, _run_distance_jobs)
    return _assemble(names, [(task.place.server, job, matrix)
                             for task, done in zip(tasks, matrices, strict=True)
                             for job, matrix in zip(task.jobs, done, strict=True)])


# Plans.

@dataclass(frozen=True)
class _Place:
    """A Dask worker and the actopo-server its tasks use."""

    worker: str
    server: str


def _field_names(fields: Sequence[str], at_least: int) -> list[str]:
    """The names as a list, checked as the server checks a job's (a name listed twice is
    refused by the server only within one job, so here for the whole list)."""
    if isinstance(fields, str):
        raise InvalidArgumentError(f"fields: '{fields}' is not a list of field names (for that "
                                   f"field alone: ['{fields}'])")
    names = list(fields)
    if len(names) < at_least:
        raise InvalidArgumentError(f"fields: {len(names)} given; at least {at_least} needed")
    seen: set[str] = set()
    for i, name in enumerate(names):
        if not isinstance(name, str) or not name:
            raise InvalidArgumentError(f"fields[{i}]: {name!r} is not a field name")
        if name in seen:
            raise InvalidArgumentError(f"fields[{i}]: '{name}' is listed twice")
        seen.add(name)
    return names


def _places(dask_client: distributed.Client, servers: Servers) -> list[_Place]:
    """The (worker, server) pairs, checked against the cluster's workers: a task bound to a
    worker the scheduler does not know would wait for it forever."""
    workers = sorted(str(w) for w in dask_client.nthreads())
    if isinstance(servers, Mapping):
        unknown = [w for w in servers if w not in workers]
        if unknown:
            raise InvalidArgumentError(f"servers: {unknown[0]!r} is not a worker of the Dask "
                                       f"cluster; its workers: {', '.join(workers) or 'none'}")
        places = [_Place(str(w), s) for w, s in servers.items()]
    else:
        if isinstance(servers, str):
            raise InvalidArgumentError(f"servers: '{servers}' is not a list of server "
                                       "addresses or a mapping of workers to servers")
        if len(servers) > len(workers):
            raise InvalidArgumentError(f"servers: {len(servers)} servers for "
                                       f"{len(workers)} Dask workers")
        places = [_Place(w, s) for w, s in zip(workers, servers, strict=False)]
    if not places:
        raise InvalidArgumentError("servers: no server given")
    for place in places:
        if not isinstance(place.server, str) or not place.server:
            raise InvalidArgumentError(f"servers: {place.server!r} (for worker "
                                       f"{place.worker}) is not a HOST:PORT address")
    return places


def _chunks(n: int, parts: int) -> list[range]:
    """[0, n) cut into `parts` contiguous ranges whose sizes differ by one at most."""
    size, extra = divmod(n, parts)
    bounds = [0]
    for k in range(parts):
        bounds.append(bounds[-1] + size + (k < extra))
    return [range(a, b) for a, b in itertools.pairwise(bounds)]


def _entries(m: int) -> int:
    return m * (m - 1) // 2


def _distance_plan(n: int, workers: int) -> list[list[list[int]]]:
    """Per worker, its diagram-distance jobs, each the ascending indices of its fields: one
    job per pair of b chunks, b the smallest giving every worker a job (at most n); the jobs
    largest first, each to the worker with the fewest entries so far."""
    b = 2
    while _entries(b) < workers and b < n:
        b += 1
    chunks = _chunks(n, b)
    jobs = [[*chunks[a], *chunks[c]] for a, c in itertools.combinations(range(b), 2)]
    plan: list[list[list[int]]] = [[] for _ in range(workers)]
    load = [0] * workers
    for job in sorted(jobs, key=len, reverse=True):
        k = min(range(workers), key=load.__getitem__)
        plan[k].append(job)
        load[k] += _entries(len(job))
    return plan


# The workers' side: these run in the Dask workers' processes, and what they return is
# pickled back (FieldResult and DistanceMatrix are plain dataclasses of numpy arrays).

@dataclass(frozen=True)
class _Task:
    place: _Place
    mesh: str
    structure: Structure
    fields: list[tuple[int, str]]  # (position in the caller's list, name), all the task reads


_T = TypeVar("_T", bound=_Task)
_R = TypeVar("_R")


@dataclass(frozen=True)
class _ChunkRun(_Task):
    algorithm: Algorithm
    parameters: dict[str, Any]
    digests: bool
    include_arrays: bool
    timeout: float | None


@dataclass(frozen=True)
class _DistanceJobs(_Task):
    jobs: list[list[str]]
    parameters: dict[str, str]
    timeout: float | None


def _run_chunk(task: _ChunkRun) -> list[FieldResult]:
    return _on_server(task, _chunk_results)


def _chunk_results(task: _ChunkRun, session: Session) -> list[FieldResult]:
    result = session.run(task.algorithm, fields=[name for _, name in task.fields],
                         parameters=task.parameters, digests=task.digests,
                         include_arrays=task.include_arrays, timeout=task.timeout)
    first = task.fields[0][0]
    return [dataclasses.replace(r, index=first + r.index) for r in result.fields]


def _run_distance_jobs(task: _DistanceJobs) -> list[DistanceMatrix]:
    return _on_server(task, _distance_matrices)


def _distance_matrices(task: _DistanceJobs, session: Session) -> list[DistanceMatrix]:
    return [distance_matrix_of(session.run("diagram-distance", fields=job,
                                           parameters=task.parameters, include_arrays=False,
                                           timeout=task.timeout))
            for job in task.jobs]


def _on_server(task: _T, work: Callable[[_T, Session], _R]) -> _R:
    """work(task, session) on a session of the task's mesh, loaded on its server for it. An
    ActopoError is raised anew, the server and the task's fields named first, and without the
    errors it was raised from: Dask pickles an error with its chain (tblib), and the gRPC error
    at the end of that chain does not pickle (Dask would send only its text)."""
    try:
        with _session(task) as session:
            return work(task, session)
    except ActopoError as e:
        error = type(e)(f"{task.place.server} ({_spans([i for i, _ in task.fields])} of "
                        f"{task.mesh}): {e.details}", e.code)
    raise error  # out of the except block: no error to chain to


def _spans(indices: list[int]) -> str:
    """Ascending positions as "fields[a:b]" slices: "fields[0:4], fields[8:12]"."""
    runs = [list(run) for _, run in itertools.groupby(enumerate(indices), lambda e: e[1] - e[0])]
    return ", ".join(f"fields[{run[0][1]}:{run[-1][1] + 1}]" for run in runs)


@contextlib.contextmanager
def _session(task: _Task) -> Iterator[Session]:
    """The task's mesh loaded on its server and a session on it, both gone afterwards (when
    the block failed, failures to close or delete are left out: the first error is the one to
    see)."""
    with Client(task.place.server) as client:
        info = client.load_mesh(task.mesh)
        session: Session | None = None
        try:
            _check_fields(info, task)
            session = client.open_session(info, structure=task.structure)
            yield session
        except BaseException:
            with contextlib.suppress(ActopoError):
                if session is not None:
                    session.close()
                client.delete_mesh(info)
            raise
        session.close()
        client.delete_mesh(info)


def _check_fields(mesh: MeshInfo, task: _Task) -> None:
    """Names an unknown field by its position in the caller's list (the server would give its
    position in this task's job)."""
    known = [f.name for f in mesh.fields]
    for i, name in task.fields:
        if name not in known:
            raise NotFoundError(f"fields[{i}]: scalar field '{name}' not found; point fields: "
                                f"{', '.join(repr(k) for k in known) or 'none'}")


# The caller's side.

def _gather(dask_client: distributed.Client, tasks: Sequence[_Task], run: Any) -> Any:
    """Runs run(task) for each task on its worker; their results in order. A worker that
    leaves lets its task run on another (which still uses the task's server), so that the
    call does not wait for it forever. The first error is raised, the other tasks cancelled."""
    futures = [dask_client.submit(run, task, workers=[task.place.worker],
                                  allow_other_workers=True, pure=False)
               for task in tasks]
    try:
        return dask_client.gather(futures)
    except BaseException:
        dask_client.cancel(futures)
        raise


def _assemble(names: list[str],
              jobs: list[tuple[str, list[str], DistanceMatrix]]) -> DistanceMatrix:
    """The n x n matrix from the jobs' (server, fields, matrix); what several jobs computed
    (entries within a chunk, each field's pairs and threshold) must agree."""
    n = len(names)
    position = {name: i for i, name in enumerate(names)}
    wasserstein, bottleneck = np.zeros((n, n)), np.zeros((n, n))
    owner = np.full((n, n), -1)  # the job that first computed each entry
    pairs, thresholds = [0] * n, [0.0] * n
    for k, (server, fields, matrix) in enumerate(jobs):
        if matrix.fields != fields:
            raise ActopoError(f"{server}: a diagram-distance job over {fields} gave a matrix "
                              f"of {matrix.fields}")
        idx = [position[f] for f in fields]
        block = np.ix_(idx, idx)
        seen = owner[block] >= 0
        differs = seen & ((wasserstein[block] != matrix.wasserstein)
                          | (bottleneck[block] != matrix.bottleneck))
        if differs.any():
            a, b = (idx[int(c)] for c in np.argwhere(differs)[0])
            raise ActopoError(f"servers {jobs[owner[a, b]][0]} and {server} disagree on the "
                              f"distance between '{names[a]}' and '{names[b]}'")
        for a, i in enumerate(idx):
            if seen[a, a] and (pairs[i], thresholds[i]) != (matrix.pairs[a],
                                                            matrix.thresholds[a]):
                raise ActopoError(f"servers {jobs[owner[i, i]][0]} and {server} disagree on "
                                  f"the pairs or the threshold of '{names[i]}'")
            pairs[i], thresholds[i] = matrix.pairs[a], matrix.thresholds[a]
        wasserstein[block] = matrix.wasserstein
        bottleneck[block] = matrix.bottleneck
        owner[block] = np.where(seen, owner[block], k)
    if (owner < 0).any():
        a, b = (int(c) for c in np.argwhere(owner < 0)[0])
        raise ActopoError(f"no job computed the distance between '{names[a]}' and "
                          f"'{names[b]}'")
    first = jobs[0][2]
    return DistanceMatrix(fields=names, wasserstein=wasserstein, bottleneck=bottleneck,
                          pairs=pairs, thresholds=thresholds, p=first.p,
                          essential=first.essential)
