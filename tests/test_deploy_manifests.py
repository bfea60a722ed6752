"""Static cross-checks of the deployment files (compose.yaml, Dockerfile, deploy/).

No container engine or cluster is needed: every YAML must parse, and the ports, names, labels,
selectors, probe ports, HAProxy's servers, the session hash header and the Prometheus targets must
agree between the files. scripts/deploy-check.sh builds and runs the image itself.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parent.parent
DEPLOY = ROOT / "deploy"
GRPC_PORT = 50051
METRICS_PORT = 9464
SESSION_HEADER = "x-actopo-session"
SERVER_IMAGE = "localhost/actopo-server"


def yaml_files() -> list[Path]:
    files = sorted(p for p in DEPLOY.rglob("*") if p.suffix in (".yaml", ".yml"))
    return [ROOT / "compose.yaml", *files]


def load_all(path: Path) -> list[dict]:
    return [d for d in yaml.safe_load_all(path.read_text()) if d is not None]


@pytest.fixture(scope="module")
def compose() -> dict:
    return yaml.safe_load((ROOT / "compose.yaml").read_text())


@pytest.fixture(scope="module")
def k8s() -> dict[tuple[str, str], dict]:
    docs = {}
    for path in sorted((DEPLOY / "k8s").glob("*.yaml")):
        for doc in load_all(path):
            if doc.get("kind") == "Kustomization":
                continue
            key = (doc["kind"], doc["metadata"]["name"])
            assert key not in docs, f"{key} defined twice"
            docs[key] = doc
    return docs


def flag(args: list[str], name: str) -> str | None:
    """Value of --name in an argv (either `--name=V` or `--name V`)."""
    for i, arg in enumerate(args):
        if arg == name and i + 1 < len(args):
            return args[i + 1]
        if arg.startswith(name + "="):
            return arg.split("=", 1)[1]
    return None


def published(ports: list) -> dict[int, int]:
    """compose ports ("[IP:]HOST:CONTAINER") -> {container: host}."""
    out = {}
    for spec in ports:
        parts = str(spec).split(":")
        out[int(parts[-1])] = int(parts[-2])
    return out


def server_services(compose: dict) -> dict[str, dict]:
    return {n: s for n, s in compose["services"].items()
            if str(s.get("image", "")).startswith(SERVER_IMAGE)}


def haproxy_configs(k8s: dict) -> dict[str, str]:
    cm = k8s[("ConfigMap", "actopo-proxy")]
    return {"compose": (DEPLOY / "haproxy.cfg").read_text(), "k8s": cm["data"]["haproxy.cfg"]}


def haproxy_sections(text: str) -> dict[str, list[str]]:
    """'section name' -> its lines (stripped, no comments or blank lines)."""
    sections: dict[str, list[str]] = {}
    current: list[str] = []
    for raw in text.splitlines():
        line = raw.split("#", 1)[0].strip() if not raw.strip().startswith("#") else ""
        if not line:
            continue
        if not raw[0].isspace():
            current = sections.setdefault(line, [])
        else:
            current.append(line)
    return sections


def haproxy_servers(text: str) -> list[tuple[str, str, int]]:
    """(name, host, port) of the actopo backend's server lines."""
    out = []
    for line in haproxy_sections(text)["backend actopo"]:
        if line.startswith("server "):
            _, name, address = line.split()[:3]
            host, port = address.strip('"').rsplit(":", 1)
            out.append((name, host, int(port)))
    return out


def haproxy_bind_port(text: str, frontend: str) -> int:
    (bind,) = [x for x in haproxy_sections(text)[f"frontend {frontend}"] if x.startswith("bind ")]
    return int(bind.split()[1].rsplit(":", 1)[1])


# --- every file ------------------------------------------------------------------------------

@pytest.mark.parametrize("path", yaml_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_yaml_parses(path):
    docs = load_all(path)
    assert docs and all(isinstance(d, dict) for d in docs)


# --- Dockerfile and compose ------------------------------------------------------------------

def test_dockerfile_targets_ports_and_healthcheck(compose):
    text = (ROOT / "Dockerfile").read_text()
    stages = set(re.findall(r"^FROM\s+\S+\s+AS\s+(\S+)", text, flags=re.M | re.I))
    assert {"build", "server", "client"} <= stages
    for service in compose["services"].values():
        if "build" in service:
            assert service["build"]["target"] in stages
    exposed = {int(p) for line in re.findall(r"^EXPOSE\s+(.+)$", text, flags=re.M)
               for p in line.split()}
    assert exposed == {GRPC_PORT, METRICS_PORT}
    assert re.search(r"^HEALTHCHECK\b.*actopo-health", text, flags=re.M | re.S)
    assert re.search(r'^VOLUME\s+\["/data"\]', text, flags=re.M)
    assert re.search(r"^USER\s+(?!0\b|root\b)\S+", text, flags=re.M)


def test_compose_servers_ports_data_and_health(compose):
    servers = server_services(compose)
    assert {"server", "server-a", "server-b"} <= set(servers)
    for name, svc in servers.items():
        cmd = svc["command"]
        assert int(flag(cmd, "--port")) == GRPC_PORT, name
        assert int(flag(cmd, "--metrics-port")) == METRICS_PORT, name
        assert flag(cmd, "--data-dir") == "/data", name
        assert any(re.search(r":/data(:ro)?$", str(v)) for v in svc["volumes"]), name
        assert "actopo-health" in " ".join(svc["healthcheck"]["test"]), name
        assert f"127.0.0.1:{GRPC_PORT}" in svc["healthcheck"]["test"], name
    assert set(published(servers["server"]["ports"])) == {GRPC_PORT, METRICS_PORT}
    for name in ("server-a", "server-b", "proxy"):
        assert compose["services"][name]["profiles"] == ["affinity"]


def test_compose_client_job_targets_the_server(compose):
    client = compose["services"]["client"]
    host, port = flag(client["command"], "--server").rsplit(":", 1)
    assert host in server_services(compose) and int(port) == GRPC_PORT
    assert client["depends_on"][host]["condition"] == "service_healthy"
    run = client["command"][client["command"].index("run"):]
    assert run[:3] == ["run", "--mesh", "sample:wavelet:32"]


# --- Kubernetes ------------------------------------------------------------------------------

def test_statefulset_ports_probes_and_flags(k8s):
    sts = k8s[("StatefulSet", "actopo-server")]
    (container,) = sts["spec"]["template"]["spec"]["containers"]
    ports = {p["name"]: p["containerPort"] for p in container["ports"]}
    assert ports == {"grpc": GRPC_PORT, "metrics": METRICS_PORT}
    assert int(flag(container["args"], "--port")) == GRPC_PORT
    assert int(flag(container["args"], "--metrics-port")) == METRICS_PORT
    for probe in ("startupProbe", "readinessProbe", "livenessProbe"):
        assert container[probe]["grpc"]["port"] == GRPC_PORT, probe
    annotations = sts["spec"]["template"]["metadata"]["annotations"]
    assert int(annotations["prometheus.io/port"]) == METRICS_PORT
    resources = container["resources"]
    assert {"cpu", "memory"} <= set(resources["requests"]) and "memory" in resources["limits"]
    # The memory budget must stay under the container's limit (the default is 75% of node RAM).
    limit = resources["limits"]["memory"]
    assert limit.endswith("Gi")
    assert int(flag(container["args"], "--memory-budget-mib")) < int(limit[:-2]) * 1024
    assert any(m["mountPath"] == "/data" for m in container["volumeMounts"])
    assert sts["spec"]["template"]["spec"]["securityContext"]["runAsNonRoot"] is True


def test_names_labels_and_selectors_agree(k8s):
    sts = k8s[("StatefulSet", "actopo-server")]
    pod_labels = sts["spec"]["template"]["metadata"]["labels"]
    selector = sts["spec"]["selector"]["matchLabels"]
    assert selector.items() <= pod_labels.items()
    headless = k8s[("Service", sts["spec"]["serviceName"])]
    assert headless["spec"]["clusterIP"] == "None"
    regular = k8s[("Service", "actopo-server")]
    assert regular["spec"].get("clusterIP") != "None"
    for svc in (headless, regular):
        assert svc["spec"]["selector"].items() <= pod_labels.items()
        assert svc["spec"]["selector"] == selector
    pdb = k8s[("PodDisruptionBudget", "actopo-server")]
    assert pdb["spec"]["selector"]["matchLabels"] == selector
    assert sts["spec"]["replicas"] >= 2


def test_service_ports_resolve_to_container_ports(k8s):
    sts = k8s[("StatefulSet", "actopo-server")]
    (container,) = sts["spec"]["template"]["spec"]["containers"]
    by_name = {p["name"]: p["containerPort"] for p in container["ports"]}
    for name in (sts["spec"]["serviceName"], "actopo-server"):
        ports = k8s[("Service", name)]["spec"]["ports"]
        resolved = {p["name"]: (p["port"], by_name.get(p["targetPort"], p["targetPort"]))
                    for p in ports}
        assert resolved == {"grpc": (GRPC_PORT, GRPC_PORT),
                            "metrics": (METRICS_PORT, METRICS_PORT)}, name


def test_proxy_deployment_and_service(k8s):
    dep = k8s[("Deployment", "actopo-proxy")]
    pod = dep["spec"]["template"]
    assert dep["spec"]["selector"]["matchLabels"].items() <= pod["metadata"]["labels"].items()
    svc = k8s[("Service", "actopo-proxy")]
    assert svc["spec"]["selector"] == dep["spec"]["selector"]["matchLabels"]
    (container,) = pod["spec"]["containers"]
    ports = {p["name"]: p["containerPort"] for p in container["ports"]}
    config = haproxy_configs(k8s)["k8s"]
    (grpc_port,) = [p for p in svc["spec"]["ports"] if p["name"] == "grpc"]
    assert grpc_port["port"] == GRPC_PORT
    assert ports[grpc_port["targetPort"]] == haproxy_bind_port(config, "grpc")
    assert ports["stats"] == haproxy_bind_port(config, "stats")
    assert container["readinessProbe"]["httpGet"]["port"] == "stats"
    assert f"monitor-uri {container['readinessProbe']['httpGet']['path']}" in \
        haproxy_sections(config)["frontend stats"]
    assert pod["spec"]["volumes"][0]["configMap"]["name"] == "actopo-proxy"
    env = {e["name"]: e["valueFrom"]["fieldRef"]["fieldPath"] for e in container["env"]}
    assert env == {"NAMESPACE": "metadata.namespace"}  # ${NAMESPACE} in the server names


# --- HAProxy ---------------------------------------------------------------------------------

@pytest.mark.parametrize("where", ["compose", "k8s"])
def test_haproxy_hashes_the_session_header_consistently(k8s, where):
    backend = haproxy_sections(haproxy_configs(k8s)[where])["backend actopo"]
    assert f"balance hdr({SESSION_HEADER})" in backend
    assert "hash-type consistent" in backend
    (defaults,) = [x.split() for x in backend if x.startswith("default-server ")]
    assert defaults[defaults.index("proto") + 1] == "h2"  # gRPC to the servers
    assert "check" in defaults
    assert "tcp-check expect binary 00000000020801" in backend  # gRPC health: SERVING


def test_haproxy_compose_servers_are_the_affinity_servers(compose, k8s):
    config = haproxy_configs(k8s)["compose"]
    affinity = {n for n, s in server_services(compose).items()
                if "affinity" in s.get("profiles", [])}
    servers = haproxy_servers(config)
    assert {host for _, host, _ in servers} == affinity
    for name, host, port in servers:
        assert name == host
        assert int(flag(compose["services"][host]["command"], "--port")) == port
    proxy = compose["services"]["proxy"]
    assert haproxy_bind_port(config, "grpc") in published(proxy["ports"])
    assert haproxy_bind_port(config, "stats") in published(proxy["ports"])
    assert any(v.startswith("./deploy/haproxy.cfg:") for v in proxy["volumes"])
    assert set(proxy["depends_on"]) == affinity


def test_haproxy_k8s_servers_are_the_statefulset_pods(k8s):
    sts = k8s[("StatefulSet", "actopo-server")]
    headless = sts["spec"]["serviceName"]
    grpc = next(p["port"] for p in k8s[("Service", headless)]["spec"]["ports"]
                if p["name"] == "grpc")
    servers = haproxy_servers(haproxy_configs(k8s)["k8s"])
    assert len(servers) >= sts["spec"]["replicas"]
    for i, (name, host, port) in enumerate(servers):
        pod = f"{sts['metadata']['name']}-{i}"
        assert name == pod
        assert host == f"{pod}.{headless}.${{NAMESPACE}}.svc.cluster.local"
        assert port == grpc


def test_haproxy_configs_differ_only_in_servers(k8s):
    configs = {where: haproxy_sections(text) for where, text in haproxy_configs(k8s).items()}
    for sections in configs.values():
        sections["backend actopo"] = [x for x in sections["backend actopo"]
                                      if not x.startswith("server ")]
    assert configs["compose"] == configs["k8s"]


# --- Prometheus ------------------------------------------------------------------------------

def test_prometheus_targets_are_server_metrics_ports(compose):
    config = yaml.safe_load((DEPLOY / "prometheus.yml").read_text())
    servers = server_services(compose)
    targets = [t for job in config["scrape_configs"] for sc in job["static_configs"]
               for t in sc["targets"]]
    assert targets
    for target in targets:
        host, port = target.rsplit(":", 1)
        assert host in servers, target
        assert int(port) == METRICS_PORT == int(flag(servers[host]["command"], "--metrics-port"))
    assert {t.rsplit(":", 1)[0] for t in targets} == set(servers)
    assert all(job.get("metrics_path", "/metrics") == "/metrics"
               for job in config["scrape_configs"])
    prom = compose["services"]["prometheus"]
    assert any(v.startswith("./deploy/prometheus.yml:") for v in prom["volumes"])
