"""actopo.distributed on a real Dask cluster: two actopo-servers on the same data directory, a
LocalCluster of two worker processes (each its own process, as on two machines). The 12 fields
of the Isabel series spread over both give, field by field, one server's job, and their distance
matrix is one server's, float for float, with the same three groups. An unknown field, a server
that is down or a worker the cluster does not have raise an error naming it; no mesh is left
behind on the servers."""

from __future__ import annotations

import contextlib
import itertools
import json
import re
import threading
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TypeVar

import dask.distributed
import numpy as np
import pytest
from dask.distributed import Client as DaskClient
from dask.distributed import LocalCluster
from harness import ServerProcess, free_port, server_process, wait_until

import actopo
from actopo.distributed import _distance_plan, distance_matrix_distributed, run_distributed

SERIES = "isabel_series_s2_tet.vtu"
README = Path(__file__).resolve().parents[1] / "README.md"
HANG_SECONDS = 60  # bounds a hang only: each call below takes a few seconds

T = TypeVar("T")


@pytest.fixture(scope="module")
def processes() -> Iterator[list[ServerProcess]]:
    """Two servers, as on two machines that see the same data."""
    with server_process() as first, server_process() as second:
        yield [first, second]


@pytest.fixture(scope="module")
def servers(processes: list[ServerProcess]) -> list[str]:
    return [p.target for p in processes]


@pytest.fixture(scope="module")
def dask_client() -> Iterator[DaskClient]:
    # The scheduler's HTTP server on a free port, not on 8787 (another test process may have
    # a cluster too).
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=":0") as cluster, DaskClient(cluster) as client:
        yield client


@pytest.fixture(scope="module")
def reference(servers: list[str]) -> tuple[list[str], actopo.JobResult,
                                           actopo.types.DistanceMatrix]:
    """One server alone: the series' fields, a persistence-diagram job over all of them, and
    their distance matrix."""
    with actopo.Client(servers[0]) as client:
        mesh = client.load_mesh(SERIES)
        names = [f.name for f in mesh.fields]
        with client.open_session(mesh) as session:
            job = session.run("persistence-diagram", fields=names, digests=True)
            matrix = session.distance_matrix(names)
        client.delete_mesh(mesh)
    return names, job, matrix


def bounded(call: Callable[[], T]) -> T:
    """call(), failing the test if it has not returned after HANG_SECONDS (on a daemon
    thread, which a hang leaves behind without holding up the test run's exit)."""
    outcome: dict[str, Any] = {}

    def run() -> None:
        try:
            outcome["value"] = call()
        except BaseException as e:
            outcome["error"] = e

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(HANG_SECONDS)
    if thread.is_alive():
        pytest.fail(f"no answer after {HANG_SECONDS} s")
    if "error" in outcome:
        raise outcome["error"]
    return outcome["value"]


def jobs_started(process: ServerProcess) -> list[str]:
    """'ALGORITHM over N fields' of each job the server started, from its log."""
    return re.findall(r"\((\S+ over \d+ fields), [^)]*\) started", "".join(process.stderr))


def no_meshes_left(servers: list[str]) -> None:
    """Every task deleted its mesh (a task still running after an error does so when done)."""
    for target in servers:
        with actopo.Client(target) as client:
            wait_until(lambda c=client: not c.list_meshes(), f"no mesh left on {target}",
                       timeout=HANG_SECONDS)


def test_fields_spread_over_two_servers_give_one_servers_job(dask_client, servers, processes,
                                                             reference):
    names, job, _ = reference
    before = [len(jobs_started(p)) for p in processes]
    results = bounded(lambda: run_distributed(dask_client, servers, SERIES,
                                              "persistence-diagram", names, digests=True,
                                              include_arrays=True))
    assert [(r.field, r.index) for r in results] == [(n, i) for i, n in enumerate(names)]
    for mine, one in zip(results, job.fields, strict=True):
        assert isinstance(mine, actopo.types.FieldResult)
        assert mine.algorithm == "persistence-diagram" and mine.summary == one.summary
        assert mine.arrays.keys() == one.arrays.keys()
        for name, values in one.arrays.items():
            np.testing.assert_array_equal(mine.arrays[name], values, err_msg=name)
        assert mine.diagram is not None
        assert mine.diagram.pairs_sha256() == one.summary["pairs_sha256"]
    # One job per server, over its contiguous half, the first half on the first worker's.
    assert [jobs_started(p)[n:] for p, n in zip(processes, before, strict=True)] == [
        ["persistence-diagram over 6 fields"]] * 2
    no_meshes_left(servers)


def test_the_distance_matrix_is_one_servers_float_for_float(dask_client, servers, processes,
                                                             reference, data_dir):
    names, _, one = reference
    before = [len(jobs_started(p)) for p in processes]
    # The mapping form: each worker's own server, here the second server on the first worker.
    workers = sorted(dask_client.nthreads())
    placed = dict(zip(workers, servers[::-1], strict=True))
    matrix = bounded(lambda: distance_matrix_distributed(dask_client, placed, SERIES, names))
    assert matrix.fields == one.fields == names
    assert np.array_equal(matrix.wasserstein, one.wasserstein)
    assert np.array_equal(matrix.bottleneck, one.bottleneck)
    assert (matrix.pairs, matrix.thresholds, matrix.p, matrix.essential) == (
        one.pairs, one.thresholds, one.p, one.essential)
    clusters = json.loads((data_dir / "series.json").read_text())["fields"]
    assert matrix.groups(3).tolist() == one.groups(3).tolist() == [
        clusters[name]["cluster"] for name in names]
    # Three chunks of 4: a job per pair of chunks, 8 fields each, two on one worker's server.
    started = sorted(len(jobs_started(p)) - n for p, n in zip(processes, before, strict=True))
    assert started == [1, 2]
    assert {j for p in processes for j in jobs_started(p)[-1:]} == {
        "diagram-distance over 8 fields"}
    no_meshes_left(servers)


def test_the_parameters_reach_the_servers(dask_client, servers, reference):
    names = reference[0][::3]  # 4 fields: chunks of 2, 1 and 1, jobs of 3 fields
    with actopo.Client(servers[1]) as client:
        mesh = client.load_mesh(SERIES)
        with client.open_session(mesh, structure="compact") as session:
            one = session.distance_matrix(names, p=1, relative_threshold=0.01, essential=True)
        client.delete_mesh(mesh)
    matrix = bounded(lambda: distance_matrix_distributed(
        dask_client, servers, SERIES, names, p=1, relative_threshold=0.01, essential=True,
        structure="compact"))
    assert (matrix.p, matrix.essential, matrix.thresholds) == (1.0, True, one.thresholds)
    assert np.array_equal(matrix.wasserstein, one.wasserstein)
    assert np.array_equal(matrix.bottleneck, one.bottleneck)


def test_an_unknown_field_is_named_with_its_server(dask_client, servers, reference):
    names = [*reference[0][:5], "velocityMag_99", reference[0][5]]
    unknown = "fields[5]: scalar field 'velocityMag_99' not found; point fields: 'velocityMag_02'"
    with pytest.raises(actopo.NotFoundError) as e:  # in the second chunk, on the second server
        bounded(lambda: run_distributed(dask_client, servers, SERIES, "critical-points", names))
    assert e.value.details.startswith(f"{servers[1]} (fields[4:7] of {SERIES}): {unknown}")
    # Chunks [0:3], [3:5] and [5:7]: the first worker's jobs read all 7 fields, the second's
    # (chunks 1 and 3) 5 of them; both find it, either may be first.
    with pytest.raises(actopo.NotFoundError) as e:
        bounded(lambda: distance_matrix_distributed(dask_client, servers, SERIES, names))
    where, found, _ = e.value.details.partition(f": {unknown}")
    assert found and where in (f"{servers[0]} (fields[0:7] of {SERIES})",
                               f"{servers[1]} (fields[0:3], fields[5:7] of {SERIES})")
    no_meshes_left(servers)


def test_a_server_that_is_down_is_named(dask_client, servers):
    down = f"127.0.0.1:{free_port()}"  # nobody listens there
    fields = ["velocityMag_02", "velocityMag_03", "velocityMag_04"]
    with pytest.raises(actopo.UnavailableError) as e:
        bounded(lambda: run_distributed(dask_client, [servers[0], down], SERIES,
                                        "critical-points", fields))
    assert e.value.details.startswith(f"{down} (fields[2:3] of {SERIES}): ")
    assert e.value.code is not None and e.value.code.name == "UNAVAILABLE"
    no_meshes_left(servers)


def test_what_dask_cannot_place_is_refused_before_any_task(dask_client, servers):
    fields = ["velocityMag_02", "velocityMag_03"]
    cases: list[tuple[Callable[[], Any], str]] = [
        (lambda: run_distributed(dask_client, {"tcp://127.0.0.1:9": servers[0]}, SERIES,
                                 "critical-points", fields),
         r"servers: 'tcp://127\.0\.0\.1:9' is not a worker of the Dask cluster"),
        (lambda: run_distributed(dask_client, [*servers, servers[0]], SERIES,
                                 "critical-points", fields),
         r"servers: 3 servers for 2 Dask workers"),
        (lambda: run_distributed(dask_client, servers, SERIES, "diagram-distance", fields),
         r"algorithm: 'diagram-distance' compares fields"),
        (lambda: run_distributed(dask_client, servers, SERIES, "critical-points",
                                 [fields[0], fields[0]]),
         r"fields\[1\]: 'velocityMag_02' is listed twice"),
        (lambda: distance_matrix_distributed(dask_client, servers, SERIES, fields[:1]),
         r"fields: 1 given; at least 2 needed"),
        (lambda: run_distributed(dask_client, servers, SERIES, "critical-points",
                                 "velocityMag_02"),
         r"fields: 'velocityMag_02' is not a list of field names"),
    ]
    for call, message in cases:
        with pytest.raises(actopo.InvalidArgumentError, match=message):
            call()


def test_the_readme_example(dask_client, servers, monkeypatch, capsys):
    """README.md's example of actopo.distributed, on this file's servers and cluster (its
    LocalCluster stands for the one started once for the file)."""
    section = README.read_text().split("### Several servers: `actopo.distributed`\n")[1]
    code = re.findall(r"```py\n(.*?)```", section, flags=re.S)[0]
    addresses = '["127.0.0.1:50051", "127.0.0.1:50052"]'
    assert addresses in code
    monkeypatch.setattr(dask.distributed, "LocalCluster",
                        lambda **_: contextlib.nullcontext(dask_client.scheduler.address))
    bounded(lambda: exec(compile(code.replace(addresses, repr(servers)), str(README), "exec"),
                         {}))
    assert capsys.readouterr().out == (
        "[(5, 'velocityMag_31', 3043), (6, 'velocityMag_32', 3167)]\n"
        "['velocityMag_02', 'velocityMag_03'] 13.543 [0 0 0 0 1 1 1 1 2 2 2 2]\n")
    no_meshes_left(servers)


@pytest.mark.parametrize("n,workers", [(2, 1), (2, 3), (3, 2), (12, 1), (12, 2), (12, 3),
                                       (12, 7), (50, 10)])
def test_the_plan_computes_every_entry(n, workers):
    """Offline: every entry is in a job, each job's fields ascend (the order of one server's
    job), the entries between chunks are in one job only, and no worker idles while another
    has two jobs."""
    plan = _distance_plan(n, workers)
    jobs = [job for worker in plan for job in worker]
    assert len(plan) == workers and all(job == sorted(set(job)) for job in jobs)
    counts = Counter(pair for job in jobs for pair in itertools.combinations(job, 2))
    assert set(counts) == set(itertools.combinations(range(n), 2))
    diagrams = Counter(i for job in jobs for i in job)
    b = diagrams[0] + 1  # each field is in b - 1 jobs
    assert set(diagrams.values()) == {b - 1} and len(jobs) == b * (b - 1) // 2
    assert sum(count > 1 for count in counts.values()) <= b * _pairs(n // b + 1)
    if any(len(worker) > 1 for worker in plan):
        assert all(plan)


def _pairs(m: int) -> int:
    return m * (m - 1) // 2
