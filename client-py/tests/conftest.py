"""Fixtures: a real actopo-server on a free loopback port, the test meshes, actopo-bench.

Environment: ACTOPO_SERVER_BIN and ACTOPO_BENCH_BIN (default: the repository's build/, or
$ACTOPO_BUILD), ACTOPO_DATA_DIR (default: ../shared/data beside the repository). Tests that need
the server are skipped, saying why, when its binary is missing.
"""

from __future__ import annotations

import contextlib
import json
import os
import queue
import subprocess
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
BUILD = Path(os.environ.get("ACTOPO_BUILD", REPO / "build"))
SERVER_BIN = Path(os.environ.get("ACTOPO_SERVER_BIN", BUILD / "server/cmd/actopo-server"))
BENCH_BIN = Path(os.environ.get("ACTOPO_BENCH_BIN", BUILD / "server/cmd/actopo-bench"))
DATA_DIR = Path(os.environ.get("ACTOPO_DATA_DIR") or REPO.parent / "shared" / "data")
STARTUP_SECONDS = 30


def _read_lines(stream, lines: queue.Queue) -> None:
    for line in stream:
        lines.put(line)
    lines.put(None)


@contextlib.contextmanager
def running_server(*flags: str) -> Iterator[str]:
    """Starts actopo-server on a free loopback port; yields its "127.0.0.1:PORT"."""
    if not SERVER_BIN.is_file():
        pytest.skip(f"actopo-server not built ({SERVER_BIN}); set ACTOPO_SERVER_BIN")
    if not DATA_DIR.is_dir():
        pytest.skip(f"test meshes not found ({DATA_DIR}); set ACTOPO_DATA_DIR")
    process = subprocess.Popen(
        [str(SERVER_BIN), "--port", "0", "--host", "127.0.0.1", "--data-dir", str(DATA_DIR),
         *flags], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lines: queue.Queue = queue.Queue()
    threading.Thread(target=_read_lines, args=(process.stdout, lines), daemon=True).start()
    errors: list[str] = []
    threading.Thread(target=lambda: errors.extend(process.stderr), daemon=True).start()
    target = None
    try:
        while target is None:
            line = lines.get(timeout=STARTUP_SECONDS)
            if line is None:
                raise RuntimeError(f"actopo-server exited ({process.wait()}): {''.join(errors)}")
            if line.startswith("actopo-server listening on "):
                target = line.split(" on ", 1)[1].strip()
        yield target
    except queue.Empty:
        raise RuntimeError(f"actopo-server did not say 'listening on' in {STARTUP_SECONDS} s")
    finally:
        process.terminate()
        try:
            process.wait(timeout=15)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


@pytest.fixture(scope="session")
def server() -> Iterator[str]:
    """The target of a server with default limits, serving DATA_DIR."""
    with running_server() as target:
        yield target


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
