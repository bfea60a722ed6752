"""Fixtures: a real actopo-server on a free loopback port, the test meshes, actopo-bench.

Environment: ACTOPO_SERVER_BIN and ACTOPO_BENCH_BIN (default: the repository's build/, or
$ACTOPO_BUILD), ACTOPO_DATA_DIR (default: ../shared/data beside the repository). Tests that need
the server are skipped, saying why (pyproject.toml's -rs prints the reasons), when its binary is
missing. With $ACTOPO_NO_SKIPS set (.ci/run sets it), a skip fails instead, as in the
repository's tests/: in CI the server, actopo-bench, the meshes and the test dependencies
(pyvista, meshio, matplotlib, openssl) are all there, so a skip would be a test that silently
stopped testing.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from harness import BENCH_BIN, DATA_DIR, ServerProcess, free_port, server_process

import actopo
from actopo._cli import main

# The Ctrl-C tests send SIGINT to this process. A shell that starts a command in the background
# without job control makes it ignore SIGINT, and Python then installs no KeyboardInterrupt
# handler: restore Python's own, so the suite means the same however it was started.
signal.signal(signal.SIGINT, signal.default_int_handler)


def _no_skips(report: pytest.TestReport | pytest.CollectReport) -> None:
    """Under $ACTOPO_NO_SKIPS, a skipped test (or module) is reported failed, with the reason."""
    if os.environ.get("ACTOPO_NO_SKIPS") and report.skipped and not hasattr(report, "wasxfail"):
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else report.longrepr
        report.outcome = "failed"
        report.longrepr = f"skipped while $ACTOPO_NO_SKIPS is set: {reason}"


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[Any]) -> Iterator[None]:
    outcome = yield
    _no_skips(outcome.get_result())


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector: pytest.Collector) -> Iterator[None]:
    outcome = yield
    _no_skips(outcome.get_result())


@pytest.fixture(scope="session")
def shared_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ServerProcess]:
    """The server most tests share: default limits, serving DATA_DIR, its Prometheus endpoint,
    where tests read what the server did (e.g. that it stopped a load), and a gate directory of
    its own, where a test holds work with shared_server.hold() (a server checks the gate for a
    file of the work's name only: it costs the other tests nothing)."""
    with server_process("--metrics-port", str(free_port()),
                        gate_dir=tmp_path_factory.mktemp("gate")) as process:
        yield process


@pytest.fixture(scope="session")
def server(shared_server: ServerProcess) -> str:
    """The target of the shared server."""
    return shared_server.target


@pytest.fixture(scope="session")
def client(server):
    import actopo

    with actopo.Client(server) as c:
        yield c


@pytest.fixture(scope="session")
def data_dir() -> Path:
    if not DATA_DIR.is_dir():
        pytest.skip(f"test meshes not found ({DATA_DIR}); set ACTOPO_DATA_DIR")
    return DATA_DIR


_bench_cache: dict[tuple[str, ...], dict] = {}


@pytest.fixture(scope="session")
def bench():
    """bench(mesh_path, algorithm, *flags) -> actopo-bench's JSON `result` (cached)."""
    if not BENCH_BIN.is_file():
        pytest.skip(f"actopo-bench not built ({BENCH_BIN}); set ACTOPO_BENCH_BIN")

    def run(mesh: str | Path, algorithm: str, *flags: str) -> dict:
        source = ["--sample", str(mesh)[7:]] if str(mesh).startswith("sample:") \
            else ["--mesh", str(mesh)]
        key = (*source, algorithm, *flags)
        if key not in _bench_cache:
            out = subprocess.run([str(BENCH_BIN), *source, "--algorithm", algorithm,
                                  "--structure", "compact", *flags, "--json"],
                                 capture_output=True, text=True, timeout=120, check=True)
            _bench_cache[key] = json.loads(out.stdout)["result"]
        return _bench_cache[key]

    return run


# The CLI in this process, and meshes loaded once per module: shared by the CLI and job tests.
@pytest.fixture
def cli(server, capsys):
    """cli(*args) -> (exit status, stdout, stderr) of `actopo --server TARGET args...`."""

    def run(*args: str) -> tuple[int, str, str]:
        status = main(["--server", server, *args])
        out, err = capsys.readouterr()
        return status, out, err

    return run


@pytest.fixture(scope="module")
def meshes(client):
    """meshes(file) -> the file loaded on the server, once per module."""
    loaded: dict[str, actopo.MeshInfo] = {}

    def load(name: str) -> actopo.MeshInfo:
        if name not in loaded:
            loaded[name] = client.load_mesh(name)
        return loaded[name]

    yield load
    for mesh in loaded.values():
        client.delete_mesh(mesh)
