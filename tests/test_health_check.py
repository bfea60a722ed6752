"""deploy/grpc_health_check.py (the image's HEALTHCHECK, `actopo-health`) against a real
actopo-server: SERVING is 0, a server that is not there 1, and `--help` is help, not a host."""

from __future__ import annotations

import subprocess
from collections.abc import Iterator

import pytest
from support import DEPLOY, PYTHON, free_port, start_server, stop, wait_for

SCRIPT = DEPLOY / "grpc_health_check.py"


def check(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(PYTHON), str(SCRIPT), *args], capture_output=True, text=True,
                          timeout=60)


@pytest.fixture(scope="module")
def target() -> Iterator[str]:
    port = free_port()
    server = start_server(port)
    try:
        address = f"127.0.0.1:{port}"
        wait_for("the server's health", lambda: check(address).returncode == 0)
        yield address
    finally:
        stop(server)


def test_a_serving_server_is_0(target):
    done = check(target)
    assert (done.returncode, done.stdout, done.stderr) == (0, f"{target}: SERVING\n", "")
    done = check(target, "no.such.Service")  # the second argument is the service asked about
    assert done.returncode == 1 and done.stderr == f"{target}: NOT_FOUND: service name unknown\n"


def test_no_server_is_1():
    address = f"127.0.0.1:{free_port()}"
    done = check(address)
    assert done.returncode == 1 and done.stderr.startswith(f"{address}: UNAVAILABLE: ")


def test_help_is_help_and_a_wrong_flag_a_usage_error():
    done = check("--help")
    assert done.returncode == 0 and done.stdout.startswith("usage: grpc_health_check.py ")
    assert "HOST:PORT" in done.stdout and done.stderr == ""
    done = check("--host", "x")
    assert done.returncode == 2 and "unrecognized arguments: --host" in done.stderr
