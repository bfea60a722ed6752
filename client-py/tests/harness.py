"""Starting actopo-server for the tests, and where the binaries and meshes are."""

from __future__ import annotations

import contextlib
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
        raise RuntimeError(
            f"actopo-server did not say 'listening on' in {STARTUP_SECONDS} s") from None
    finally:
        process.terminate()
        try:
            process.wait(timeout=15)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
