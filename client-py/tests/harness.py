"""Starting actopo-server for the tests, and where the binaries and meshes are."""

from __future__ import annotations

import asyncio
import contextlib
import os
import queue
import re
import signal
import socket
import subprocess
import sys
import threading
import time
import urllib.request
from collections.abc import Awaitable, Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TypeVar

import pytest

REPO = Path(__file__).resolve().parents[2]
BUILD = Path(os.environ.get("ACTOPO_BUILD", REPO / "build"))
SERVER_BIN = Path(os.environ.get("ACTOPO_SERVER_BIN", BUILD / "server/cmd/actopo-server"))
BENCH_BIN = Path(os.environ.get("ACTOPO_BENCH_BIN", BUILD / "server/cmd/actopo-bench"))
DATA_DIR = Path(os.environ.get("ACTOPO_DATA_DIR") or REPO.parent / "shared" / "data")
STARTUP_SECONDS = 30
STOP_SECONDS = 15
WAIT_SECONDS = 60.0
"""Only bounds a hang: what a test waits for happens within a fraction of a second."""

T = TypeVar("T")


def free_port() -> int:
    """A loopback port that was free a moment ago."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _read_lines(stream, lines: queue.Queue) -> None:
    for line in stream:
        lines.put(line)
    lines.put(None)


@dataclass
class ServerProcess:
    """A running actopo-server child: its target, and readings of the process."""

    process: subprocess.Popen
    target: str = ""
    metrics_port: int = 0
    stderr: list[str] = field(default_factory=list)
    gate_dir: Path | None = None
    """--test-gate-dir, where hold() puts its files."""

    @property
    def pid(self) -> int:
        return self.process.pid

    @property
    def port(self) -> int:
        return int(self.target.rsplit(":", 1)[1])

    def threads(self) -> int:
        """The process's thread count (/proc/PID/status)."""
        status = Path(f"/proc/{self.pid}/status").read_text()
        return int(next(line.split()[1] for line in status.splitlines()
                        if line.startswith("Threads:")))

    def metric(self, name: str) -> float:
        """The value of an unlabelled metric on the Prometheus endpoint (--metrics-port)."""
        url = f"http://127.0.0.1:{self.metrics_port}/metrics"
        for line in self._metrics_text().splitlines():
            parts = line.split()
            if len(parts) == 2 and parts[0] == name:
                return float(parts[1])
        raise KeyError(f"{name} not in {url}")

    def requests(self, rpc: str) -> dict[int, int]:
        """The calls of `rpc` the server has answered, by gRPC status code number (its
        actopo_requests_total counter; the server counts a call once its work is over)."""
        text = self._metrics_text()
        counts = {}
        for labels, value in re.findall(r'^actopo_requests_total\{([^}]*)\} (\S+)$', text, re.M):
            pairs = dict(re.findall(r'(\w+)="([^"]*)"', labels))
            if pairs.get("rpc") == rpc:
                counts[int(pairs["code"])] = int(float(value))
        return counts

    def _metrics_text(self) -> str:
        if not self.metrics_port:
            raise RuntimeError("the server was started without --metrics-port")
        url = f"http://127.0.0.1:{self.metrics_port}/metrics"
        with urllib.request.urlopen(url, timeout=10) as response:
            return str(response.read().decode())

    @contextlib.contextmanager
    def hold(self, name: str) -> Iterator[Hold]:
        """Holds the server's work named `name` at its start for the duration of a with block:
        "RunJob" (a job, once its client has the job id), "LoadMesh", "LoadMeshWithProgress"
        and its phases ("LoadMeshWithProgress/encode"), "UploadMesh", "OpenSession", or an
        offloaded relation call by its RPC's name. Work that starts meanwhile waits until
        Hold.release() or the end of the block, whatever the test's outcome. Needs a server
        started with a gate_dir (the shared server has one)."""
        if self.gate_dir is None:
            raise RuntimeError("the server was started without a gate_dir (--test-gate-dir)")
        hold = Hold(self, self.gate_dir, name.replace("/", "."))
        # The server removes NAME.held as the work it held goes on: a hold of the same name
        # just released must not be taken for this one.
        wait_until(lambda: not hold.is_held, f"the last hold of {hold.name} to be let go")
        hold.path.touch(exist_ok=False)
        try:
            yield hold
        finally:
            hold.release()

    def signal(self, number: signal.Signals) -> None:
        self.process.send_signal(number)

    def stop(self) -> int:
        """SIGTERM, then SIGKILL after STOP_SECONDS; the exit code."""
        if self.process.poll() is None:
            self.process.terminate()
        try:
            return self.process.wait(timeout=STOP_SECONDS)
        except subprocess.TimeoutExpired:
            self.process.kill()
            return self.process.wait()


@dataclass
class Hold:
    """A hold of ServerProcess.hold(): while the file `path` exists, the server's work named
    `name` waits at its start, and the server says with the file `held_path` that some does."""

    server: ServerProcess = field(repr=False)
    gate_dir: Path
    name: str

    @property
    def path(self) -> Path:
        return self.gate_dir / self.name

    @property
    def held_path(self) -> Path:
        return self.gate_dir / f"{self.name}.held"

    @property
    def is_held(self) -> bool:
        """Whether some work of this name waits at the gate now."""
        return self.held_path.exists()

    def wait_held(self, timeout: float = WAIT_SECONDS) -> None:
        """Waits until work of this name waits at the gate (fails at once if the server
        exits)."""
        def held() -> bool:
            if self.server.process.poll() is not None:
                raise AssertionError(f"actopo-server exited ({self.server.process.returncode}) "
                                     f"before {self.name} was held: {''.join(self.server.stderr)}")
            return self.is_held

        wait_until(held, f"{self.name} held on the server", timeout)

    def interrupt_when_held(self, sent: threading.Event) -> None:
        """SIGINT to this process, as if the user pressed Ctrl-C, once work of this name is held
        (run on a thread of its own while the main thread waits for that work); `sent` is set
        after."""
        self.wait_held()
        os.kill(os.getpid(), signal.SIGINT)
        sent.set()

    def release(self) -> None:
        """Lets the held work, and work of this name that starts from now on, go on."""
        self.path.unlink(missing_ok=True)


def start_server(*flags: str, port: int = 0,
                 gate_dir: str | os.PathLike[str] | None = None) -> ServerProcess:
    """Starts actopo-server on 127.0.0.1:`port` (0: a free one) serving DATA_DIR, and waits
    until it says where it listens (and where its metrics are, with --metrics-port). With a
    `gate_dir` (an empty directory), ServerProcess.hold() holds its work."""
    if not SERVER_BIN.is_file():
        pytest.skip(f"actopo-server not built ({SERVER_BIN}); set ACTOPO_SERVER_BIN")
    if not DATA_DIR.is_dir():
        pytest.skip(f"test meshes not found ({DATA_DIR}); set ACTOPO_DATA_DIR")
    if gate_dir is not None:
        flags = (*flags, "--test-gate-dir", str(gate_dir))
    process = subprocess.Popen(
        [str(SERVER_BIN), "--port", str(port), "--host", "127.0.0.1", "--data-dir",
         str(DATA_DIR), *flags], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    server = ServerProcess(process, gate_dir=None if gate_dir is None else Path(gate_dir))
    lines: queue.Queue = queue.Queue()
    threading.Thread(target=_read_lines, args=(process.stdout, lines), daemon=True).start()
    threading.Thread(target=lambda: server.stderr.extend(process.stderr), daemon=True).start()
    wants_metrics = "--metrics-port" in flags and flags[flags.index("--metrics-port") + 1] != "0"
    try:
        while not server.target or (wants_metrics and not server.metrics_port):
            line = lines.get(timeout=STARTUP_SECONDS)
            if line is None:
                raise RuntimeError(
                    f"actopo-server exited ({process.wait()}): {''.join(server.stderr)}")
            if line.startswith("actopo-server listening on "):
                server.target = line.split(" on ", 1)[1].strip()
            elif line.startswith("actopo-server metrics on "):
                address = line.split(" on ", 1)[1].strip().split("/", 1)[0]
                server.metrics_port = int(address.rsplit(":", 1)[1])
    except BaseException as e:
        server.stop()
        if isinstance(e, queue.Empty):
            raise RuntimeError(
                f"actopo-server did not say 'listening on' in {STARTUP_SECONDS} s") from None
        raise
    return server


@contextlib.contextmanager
def server_process(*flags: str, port: int = 0,
                   gate_dir: str | os.PathLike[str] | None = None) -> Iterator[ServerProcess]:
    """start_server() for the duration of a with block; stops it (if still running) after."""
    server = start_server(*flags, port=port, gate_dir=gate_dir)
    try:
        yield server
    finally:
        server.stop()


@contextlib.contextmanager
def running_server(*flags: str) -> Iterator[str]:
    """Starts actopo-server on a free loopback port; yields its "127.0.0.1:PORT"."""
    with server_process(*flags) as server:
        yield server.target


def wait_until(predicate: Callable[[], T], what: str, timeout: float = WAIT_SECONDS,
               interval: float = 0.01) -> T:
    """Calls `predicate` every `interval` seconds until it returns something true, and returns
    that. After `timeout` seconds (which only bound a hang) raises AssertionError saying that
    `what` did not happen."""
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() >= deadline:
            raise AssertionError(f"waited {timeout:g} s for {what} (last: {value!r})")
        time.sleep(interval)


async def wait_until_async(predicate: Callable[[], Awaitable[T]], what: str,
                           timeout: float = WAIT_SECONDS, interval: float = 0.01) -> T:
    """wait_until() in a coroutine: awaits `predicate()`, and sleeps without blocking the
    event loop."""
    deadline = time.monotonic() + timeout
    while True:
        value = await predicate()
        if value:
            return value
        if time.monotonic() >= deadline:
            raise AssertionError(f"waited {timeout:g} s for {what} (last: {value!r})")
        await asyncio.sleep(interval)


# Runs the CLI as `python -m actopo` would, with Python's own SIGINT handler even when this
# process ignores SIGINT (as pytest-xdist's workers do), so the tests' SIGINT reaches it as a
# user's Ctrl-C. Set here, not in a preexec_fn: a preexec_fn makes subprocess fork() instead of
# vfork(), the fork runs gRPC's fork handlers, and gRPC's event engine then restarts its poller
# in the child, which can crash on the descriptors closed before exec (grpc/grpc#43055): the
# CLI then never starts.
_CLI_WITH_SIGINT = ("import runpy, signal, sys; "
                    "signal.signal(signal.SIGINT, signal.default_int_handler); "
                    "sys.argv[0] = 'actopo'; runpy.run_module('actopo', run_name='__main__')")


def start_cli(*args: str) -> subprocess.Popen[str]:
    """Starts `actopo ARGS...` in a new Python process, its output as text on pipes."""
    return subprocess.Popen([sys.executable, "-c", _CLI_WITH_SIGINT, *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def run_cli(server: str, *args: str, cwd: str | os.PathLike[str] | None = None,
            timeout: float = 300, env: dict[str, str] | None = None
            ) -> subprocess.CompletedProcess[str]:
    """`actopo ARGS...` run to its end in a new Python process as a user types it, after the
    README's `export ACTOPO_SERVER=...` (`server`): its exit status, stdout and stderr."""
    return subprocess.run([sys.executable, "-m", "actopo", *args], capture_output=True,
                          text=True, timeout=timeout, cwd=cwd,
                          env={**os.environ, "ACTOPO_SERVER": server, **(env or {})})
