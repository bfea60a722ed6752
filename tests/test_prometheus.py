"""Prometheus for real: Debian's prometheus scrapes a running actopo-server with the scrape job
and alert rules of deploy/, and its HTTP API shows the target up, the actopo metrics with values
after a job, the rules loaded, and ActopoServerDown pending once the server is gone. promtool
checks the configuration and rules and runs their unit tests (deploy/alerts_test.yml).

Skipped, saying why, without Debian's prometheus package (scripts/install-deps.sh installs it) or
without a built server ($ACTOPO_BUILD, default build/).
"""

from __future__ import annotations

import json
import signal
import subprocess
import urllib.parse
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml
from support import DEPLOY, PYTHON, free_port, need, need_server, start, stop, wait_for

ALERTS = ["ActopoMemoryBudgetNearlyFull", "ActopoServerDown", "ActopoServerErrors",
          "ActopoSlowJobs"]


def test_promtool_checks_the_configuration_and_the_rules():
    promtool = need("promtool", "prometheus")
    for args in (["check", "config", "prometheus.yml"], ["check", "rules", "alerts.yml"],
                 ["test", "rules", "alerts_test.yml"]):
        run = subprocess.run([promtool, *args], cwd=DEPLOY, capture_output=True, text=True)
        assert run.returncode == 0, f"promtool {' '.join(args)}:\n{run.stdout}{run.stderr}"


class Prometheus:
    def __init__(self, port: int) -> None:
        self.base = f"http://127.0.0.1:{port}/api/v1"

    def get(self, path: str, **params: str) -> Any:
        url = f"{self.base}/{path}"
        if params:
            url += "?" + urllib.parse.urlencode(params)
        try:
            with urllib.request.urlopen(url, timeout=5) as response:
                body = json.load(response)
        except OSError:
            return None
        assert body["status"] == "success", body
        return body["data"]

    def value(self, query: str) -> float | None:
        data = self.get("query", query=query)
        if not data or not data["result"]:
            return None
        return float(data["result"][0]["value"][1])


@pytest.fixture
def server_and_prometheus(tmp_path: Path) -> Iterator[tuple[subprocess.Popen, str, Prometheus]]:
    prometheus = need("prometheus", "prometheus")
    server_bin = need_server()
    grpc_port, metrics_port, web_port = free_port(), free_port(), free_port()
    server = start([str(server_bin), "--host", "127.0.0.1", "--port", str(grpc_port),
                    "--metrics-port", str(metrics_port)])
    # deploy/prometheus.yml's job and rules, scraping this server every second.
    config = yaml.safe_load((DEPLOY / "prometheus.yml").read_text())
    config["global"] = {"scrape_interval": "1s", "evaluation_interval": "1s"}
    config["rule_files"] = [str(DEPLOY / f) for f in config["rule_files"]]
    job = config["scrape_configs"][0]
    job["static_configs"] = [{"targets": [f"127.0.0.1:{metrics_port}"]}]
    config["scrape_configs"] = [job]
    (tmp_path / "prometheus.yml").write_text(yaml.safe_dump(config))
    prom = start([prometheus, f"--config.file={tmp_path / 'prometheus.yml'}",
                  f"--storage.tsdb.path={tmp_path / 'data'}",
                  f"--web.listen-address=127.0.0.1:{web_port}"],
                 log=tmp_path / "prom.log")
    try:
        yield server, f"127.0.0.1:{grpc_port}", Prometheus(web_port)
    finally:
        stop(prom, server)


def test_prometheus_scrapes_the_server_and_the_alerts_follow(server_and_prometheus):
    server, target, prom = server_and_prometheus
    wait_for("the target to be up", lambda: prom.value('up{job="actopo-server"}') == 1)

    rules = wait_for("the alert rules", lambda: prom.get("rules"))
    loaded = sorted(r["name"] for g in rules["groups"] for r in g["rules"])
    assert loaded == ALERTS
    assert all(r["health"] == "ok" for g in rules["groups"] for r in g["rules"])

    job = subprocess.run([str(PYTHON), "-m", "actopo", "--server", target, "run", "--sample",
                          "jittered:12", "--algorithm", "critical-points", "--structure",
                          "actopo"], capture_output=True, text=True, timeout=120)
    assert job.returncode == 0, job.stdout + job.stderr
    count = 'actopo_job_duration_seconds_count{algorithm="critical-points",structure="actopo"}'
    assert wait_for("the job in the metrics", lambda: prom.value(count)) == 1
    assert wait_for("the load in the requests",
                    lambda: prom.value('actopo_requests_total{rpc="LoadMesh",code="0"}')) >= 1
    assert prom.value("actopo_memory_budget_limit_bytes") > 0
    assert prom.value("actopo_process_resident_bytes") > 0
    assert 0 < prom.value("actopo_process_heap_bytes") < prom.value("actopo_process_resident_bytes")
    assert prom.value("actopo_buffer_hits_total + actopo_buffer_misses_total") > 0
    # Nothing is wrong yet.
    assert prom.get("alerts")["alerts"] == []

    server.send_signal(signal.SIGTERM)
    server.wait(timeout=10)
    wait_for("the target to be down", lambda: prom.value('up{job="actopo-server"}') == 0)
    # It fires after a minute down; until then it is pending.
    pending = wait_for("ActopoServerDown to be pending", lambda: [
        a for a in prom.get("alerts")["alerts"] if a["labels"]["alertname"] == "ActopoServerDown"])
    assert pending[0]["state"] == "pending"
    assert pending[0]["labels"]["severity"] == "critical"
