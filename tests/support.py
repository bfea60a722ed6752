"""What the tests that run real deployment components (Prometheus, HAProxy) share: where the
repository and the built server are, free ports, waiting, and starting and stopping processes."""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parent.parent
DEPLOY = ROOT / "deploy"
BUILD = Path(os.environ.get("ACTOPO_BUILD", ROOT / "build"))
SERVER_BIN = BUILD / "server/cmd/actopo-server"
PYTHON = ROOT / ".venv/bin/python"


def need(tool: str, package: str) -> str:
    """The path of `tool`, else skip the test naming the Debian package that has it."""
    path = shutil.which(tool) or (f"/usr/sbin/{tool}" if Path(f"/usr/sbin/{tool}").is_file()
                                  else None)
    if path is None:
        pytest.skip(f"{tool} not installed (Debian package {package}; scripts/install-deps.sh)")
    return path


def need_server() -> Path:
    if not SERVER_BIN.is_file():
        pytest.skip(f"actopo-server not built ({SERVER_BIN}); set ACTOPO_BUILD")
    return SERVER_BIN


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def wait_for(what: str, check: Callable[[], Any], timeout: float = 60) -> Any:
    """Polls `check` every half second until it returns something true, and returns that."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = check()
        if value:
            return value
        time.sleep(0.5)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


def start_server(port: int, *flags: str) -> subprocess.Popen:
    """actopo-server on 127.0.0.1:`port`; the caller waits for it to answer."""
    return subprocess.Popen([str(need_server()), "--host", "127.0.0.1", "--port", str(port),
                             *flags], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def start(args: Sequence[str], log: Path | None = None) -> subprocess.Popen:
    """Starts `args` with its stdout and stderr into the file `log` (default: nowhere)."""
    if log is None:
        return subprocess.Popen(list(args), stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL)
    with open(log, "w") as out:
        return subprocess.Popen(list(args), stdout=out, stderr=subprocess.STDOUT)


def stop(*processes: subprocess.Popen, how: signal.Signals = signal.SIGTERM) -> None:
    """Signals each process still running and waits for it (SIGKILL after 10 s)."""
    for p in processes:
        if p.poll() is None:
            p.send_signal(how)
    for p in processes:
        try:
            p.wait(timeout=10)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()
