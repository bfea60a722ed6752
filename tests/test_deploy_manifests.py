"""Static cross-checks of the deployment files (compose.yaml, Dockerfile, deploy/).

No container engine or cluster is needed: every YAML must parse, and the ports, names, labels,
selectors, probe ports, Envoy addresses, the session hash header and the Prometheus targets must
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


def envoy_configs(compose: dict, k8s: dict) -> dict[str, dict]:
    cm = k8s[("ConfigMap", "actopo-envoy")]
    return {"compose": yaml.safe_load((DEPLOY / "envoy.yaml").read_text()),
            "k8s": yaml.safe_load(cm["data"]["envoy.yaml"])}


def envoy_endpoints(config: dict) -> list[tuple[str, int]]:
    out = []
    for cluster in config["static_resources"]["clusters"]:
        for group in cluster["load_assignment"]["endpoints"]:
            for ep in group["lb_endpoints"]:
                sock = ep["endpoint"]["address"]["socket_address"]
                out.append((sock["address"], int(sock["port_value"])))
    return out


def envoy_listener_port(config: dict) -> int:
    (listener,) = config["static_resources"]["listeners"]
    return int(listener["address"]["socket_address"]["port_value"])


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
    for name in ("server-a", "server-b", "envoy"):
        assert compose["services"][name]["profiles"] == ["affinity"]


def test_compose_client_job_targets_the_server(compose):
    client = compose["services"]["client"]
    host, port = flag(client["command"], "--server").rsplit(":", 1)
    assert host in server_services(compose) and int(port) == GRPC_PORT
    assert client["depends_on"][host]["condition"] == "service_healthy"
    assert client["command"][client["command"].index("run"):][:3] == ["run", "--mesh", "sample:wavelet:32"]


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


def test_envoy_deployment_and_service(k8s):
    dep = k8s[("Deployment", "actopo-envoy")]
    pod = dep["spec"]["template"]
    assert dep["spec"]["selector"]["matchLabels"].items() <= pod["metadata"]["labels"].items()
    svc = k8s[("Service", "actopo-envoy")]
    assert svc["spec"]["selector"] == dep["spec"]["selector"]["matchLabels"]
    (container,) = pod["spec"]["containers"]
    ports = {p["name"]: p["containerPort"] for p in container["ports"]}
    config = yaml.safe_load(k8s[("ConfigMap", "actopo-envoy")]["data"]["envoy.yaml"])
    (grpc_port,) = [p for p in svc["spec"]["ports"] if p["name"] == "grpc"]
    assert ports[grpc_port["targetPort"]] == envoy_listener_port(config)
    assert pod["spec"]["volumes"][0]["configMap"]["name"] == "actopo-envoy"


# --- Envoy -----------------------------------------------------------------------------------

@pytest.mark.parametrize("where", ["compose", "k8s"])
def test_envoy_hashes_the_session_header(compose, k8s, where):
    config = envoy_configs(compose, k8s)[where]
    clusters = {c["name"]: c for c in config["static_resources"]["clusters"]}
    (listener,) = config["static_resources"]["listeners"]
    (hcm,) = listener["filter_chains"][0]["filters"]
    routes = [r for vh in hcm["typed_config"]["route_config"]["virtual_hosts"] for r in vh["routes"]]
    assert routes
    for route in routes:
        action = route["route"]
        assert action["cluster"] in clusters
        headers = [h["header"]["header_name"] for h in action["hash_policy"]]
        assert headers == [SESSION_HEADER]
        cluster = clusters[action["cluster"]]
        assert cluster["lb_policy"] == "RING_HASH"
        options = cluster["typed_extension_protocol_options"][
            "envoy.extensions.upstreams.http.v3.HttpProtocolOptions"]
        assert "http2_protocol_options" in options["explicit_http_config"]  # gRPC upstream
        assert "grpc_health_check" in cluster["health_checks"][0]


def test_envoy_compose_endpoints_are_the_affinity_servers(compose, k8s):
    config = envoy_configs(compose, k8s)["compose"]
    affinity = {n for n, s in server_services(compose).items()
                if "affinity" in s.get("profiles", [])}
    endpoints = envoy_endpoints(config)
    assert {host for host, _ in endpoints} == affinity
    for host, port in endpoints:
        assert int(flag(compose["services"][host]["command"], "--port")) == port
    envoy = compose["services"]["envoy"]
    assert envoy_listener_port(config) in published(envoy["ports"])
    assert any(v.startswith("./deploy/envoy.yaml:") for v in envoy["volumes"])
    assert set(envoy["depends_on"]) == affinity


def test_envoy_k8s_endpoint_is_the_headless_service(compose, k8s):
    config = envoy_configs(compose, k8s)["k8s"]
    sts = k8s[("StatefulSet", "actopo-server")]
    headless = k8s[("Service", sts["spec"]["serviceName"])]
    grpc = next(p["port"] for p in headless["spec"]["ports"] if p["name"] == "grpc")
    assert envoy_endpoints(config) == [(headless["metadata"]["name"], grpc)]


def test_envoy_configs_differ_only_in_endpoints(compose, k8s):
    configs = envoy_configs(compose, k8s)
    for config in configs.values():
        for cluster in config["static_resources"]["clusters"]:
            cluster.pop("load_assignment")
            cluster.pop("dns_refresh_rate", None)
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
    assert all(job.get("metrics_path", "/metrics") == "/metrics" for job in config["scrape_configs"])
    prom = compose["services"]["prometheus"]
    assert any(v.startswith("./deploy/prometheus.yml:") for v in prom["volumes"])
