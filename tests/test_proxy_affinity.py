"""Session affinity for real: Debian's HAProxy runs deploy/haproxy.cfg in front of real
actopo-servers (its two, plus a third server line like theirs), and Python clients with fixed
affinity keys load meshes, open sessions and query them through it.

- Every call of a key reaches one server: each session exists on exactly one server, and that
  server counted every query sent for it through the proxy. Both servers get keys.
- A server that drains (SIGTERM) leaves the ring: its keys move to the others, whose keys and
  sessions stay where they were. When it comes back, its keys move back and the others still
  stay.
- HAProxy accepts the compose and the Kubernetes configurations as shipped (`haproxy -c`).

Skipped, saying why, without Debian's haproxy package (scripts/install-deps.sh installs it) or
without a built server ($ACTOPO_BUILD, default build/).
"""

from __future__ import annotations

import csv
import io
import os
import subprocess
import urllib.request
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
import yaml
from support import DEPLOY, free_port, need, start, start_server, stop, wait_for

import actopo

SERVERS = ["server-a", "server-b", "server-c"]
KEYS = [f"workflow-{i}" for i in range(16)]
SAMPLE = "jittered:6"
QUERIES = 5


def local_config(text: str, listen: int, stats: int, backends: dict[str, int]) -> str:
    """deploy/haproxy.cfg with loopback addresses for its listeners and its two servers, and a
    third server line like theirs (with two, a hash that is not consistent would pass too)."""
    text = text.replace("bind :8080 ", f"bind 127.0.0.1:{listen} ")
    text = text.replace("bind :8404", f"bind 127.0.0.1:{stats}")
    lines = text.splitlines()
    last = max(i for i, line in enumerate(lines) if line.strip().startswith("server "))
    for name, port in backends.items():
        line = f"    server {name} 127.0.0.1:{port}"
        found = [i for i, x in enumerate(lines) if x == f"    server {name} {name}:50051"]
        if found:
            lines[found[0]] = line
        else:
            last += 1
            lines.insert(last, line)
    return "\n".join(lines) + "\n"


@dataclass
class Deployment:
    proxy: str
    stats_port: int
    ports: dict[str, int]
    servers: dict[str, subprocess.Popen]

    def backend_status(self) -> dict[str, str]:
        """HAProxy's view of each server of the actopo backend (UP, DOWN, ...)."""
        url = f"http://127.0.0.1:{self.stats_port}/stats;csv"
        try:
            with urllib.request.urlopen(url, timeout=5) as response:
                text = response.read().decode().lstrip("# ")
        except OSError:
            return {}
        rows = csv.DictReader(io.StringIO(text))
        return {r["svname"]: r["status"] for r in rows
                if r["pxname"] == "actopo" and r["svname"] in self.ports}

    def wait_status(self, want: dict[str, str]) -> None:
        wait_for(f"HAProxy to see {want}",
                 lambda: all(self.backend_status().get(k, "").startswith(v)
                             for k, v in want.items()))

    def start(self, name: str) -> None:
        self.servers[name] = start_server(self.ports[name])

    def direct(self, name: str) -> actopo.Client:
        return actopo.Client(f"127.0.0.1:{self.ports[name]}")

    def answers(self, name: str) -> bool:
        try:
            with self.direct(name) as client:
                client.server_info()
            return True
        except actopo.UnavailableError:
            return False


@pytest.fixture
def deployment(tmp_path: Path) -> Iterator[Deployment]:
    haproxy = need("haproxy", "haproxy")
    listen, stats = free_port(), free_port()
    ports = {name: free_port() for name in SERVERS}
    config = tmp_path / "haproxy.cfg"
    config.write_text(local_config((DEPLOY / "haproxy.cfg").read_text(), listen, stats, ports))
    d = Deployment(f"127.0.0.1:{listen}", stats, ports, {})
    for name in ports:
        d.start(name)
    # HAProxy counts a server up until its first check, which it may delay by up to an interval
    # (2 s) to spread checks: its status alone does not say the server listens yet, and a first
    # call could reach one still starting (503, seen once in CI).
    for name in ports:
        wait_for(f"{name} to answer", lambda name=name: d.answers(name))
    proxy = start([haproxy, "-f", str(config)], log=tmp_path / "haproxy.log")
    try:
        d.wait_status(dict.fromkeys(SERVERS, "UP"))
        yield d
    finally:
        stop(proxy, *d.servers.values())
        print((tmp_path / "haproxy.log").read_text())


def open_workflow(proxy: str, key: str) -> str:
    """Through the proxy with `key`: a mesh, a session on it, and its id."""
    with actopo.Client(proxy, affinity_key=key) as client:
        mesh = client.sample(SAMPLE)
        return client.open_session(mesh, structure="compact").session_id


def query(proxy: str, key: str, session_id: str) -> None:
    """QUERIES relation calls on the session through the proxy, each on a new connection."""
    for _ in range(QUERIES):
        with actopo.Client(proxy, affinity_key=key) as client:
            offsets, _ = client.session(session_id).relation("vertex_edges", [0, 1, 2])
            assert len(offsets) == 4


def home(d: Deployment, session_id: str) -> list[str]:
    """The servers that hold the session."""
    found = []
    for name, process in d.servers.items():
        if process.poll() is not None:
            continue
        with d.direct(name) as client:
            try:
                client.get_session(session_id)
                found.append(name)
            except actopo.NotFoundError:
                pass
    return found


def queries_counted(d: Deployment, name: str, session_id: str) -> int:
    with d.direct(name) as client:
        return client.session(session_id).stats().relation_queries.count


def test_a_key_keeps_to_its_server_and_only_a_leaving_servers_keys_move(deployment):
    d = deployment
    sessions = {key: open_workflow(d.proxy, key) for key in KEYS}
    homes = {}
    for key, session_id in sessions.items():
        servers = home(d, session_id)
        assert len(servers) == 1, f"{key}: session {session_id} on {servers}"
        homes[key] = servers[0]
    assert set(homes.values()) == set(SERVERS), homes

    for key, session_id in sessions.items():
        query(d.proxy, key, session_id)
        assert queries_counted(d, homes[key], session_id) == QUERIES, key

    # server-b drains, as in a rolling update: it answers NOT_SERVING, then exits.
    stop(d.servers["server-b"])
    d.wait_status({"server-a": "UP", "server-b": "DOWN", "server-c": "UP"})
    moved = {}
    for key, session_id in sessions.items():
        if homes[key] != "server-b":
            query(d.proxy, key, session_id)  # untouched
            continue
        # Its calls now reach another server, where that session does not exist.
        with actopo.Client(d.proxy, affinity_key=key) as client, \
                pytest.raises(actopo.NotFoundError):
            client.get_session(session_id)
        moved[key] = home(d, open_workflow(d.proxy, key))
        assert moved[key] in (["server-a"], ["server-c"]), key
    assert moved

    # server-b is back (a fresh process, no sessions): its keys return to it, the rest stay.
    d.start("server-b")
    d.wait_status(dict.fromkeys(SERVERS, "UP"))
    for key, session_id in sessions.items():
        if homes[key] != "server-b":
            query(d.proxy, key, session_id)
            assert queries_counted(d, homes[key], session_id) == 3 * QUERIES, key
        else:
            assert home(d, open_workflow(d.proxy, key)) == ["server-b"], key


def test_haproxy_accepts_the_shipped_configurations(tmp_path):
    haproxy = need("haproxy", "haproxy")
    cm = next(doc for doc in yaml.safe_load_all((DEPLOY / "k8s/haproxy.yaml").read_text())
              if doc and doc["kind"] == "ConfigMap")
    (tmp_path / "k8s.cfg").write_text(cm["data"]["haproxy.cfg"])
    for config in (DEPLOY / "haproxy.cfg", tmp_path / "k8s.cfg"):
        check = subprocess.run([haproxy, "-c", "-f", str(config)], capture_output=True, text=True,
                               env={**os.environ, "NAMESPACE": "default"})
        assert check.returncode == 0, f"{config}:\n{check.stdout}{check.stderr}"
