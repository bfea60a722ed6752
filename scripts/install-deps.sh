#!/usr/bin/env bash
# Installs everything the build, the tests and the demo need, and nothing twice.
# Idempotent: a second run checks and exits quickly.
#   scripts/install-deps.sh            Debian packages + Python virtual environment (.venv)
#   scripts/install-deps.sh --no-venv  Debian packages only (used by the Docker build stage)
set -euo pipefail

here=$(cd "$(dirname "$0")/.." && pwd)
want_venv=1
[[ "${1:-}" == "--no-venv" ]] && want_venv=0

debian_packages=(
  build-essential cmake ninja-build pkg-config git ca-certificates
  libabsl-dev nlohmann-json3-dev libssl-dev libexpat1-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libvtk9-dev libdeflate-dev
  libgrpc++-dev protobuf-compiler-grpc libprotobuf-dev protobuf-compiler
  prometheus-cpp-dev
  python3 python3-venv python3-dev
)

# Fuzzing (make fuzz, and make test's short runs) and the thread-safety analysis: clang with
# libFuzzer; clang-format for the C++ house style (make check-format); Prometheus and promtool
# for tests/test_prometheus.py (the scrape job and alert rules of deploy/); HAProxy for the
# session-affinity tests (deploy/haproxy.cfg); the openssl command for the TLS tests' certificates.
# Not in the images.
((want_venv)) && debian_packages+=(clang-14 clang-format-14 libfuzzer-14-dev libclang-rt-14-dev prometheus haproxy
                                   openssl)
# ParaView for the plugin (paraview/) and its headless test with pvbatch, numpy for ParaView's
# Python (the plugin converts arrays with it); python3-paraview is unpacked below.
((want_venv)) && debian_packages+=(paraview python3-numpy)

missing=()
# npm (for buf, a development tool): the machine's own Node.js when present, else Debian's.
if ((want_venv)) && ! command -v npm >/dev/null 2>&1; then missing+=(nodejs npm); fi
for p in "${debian_packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

sudo=""
[[ $(id -u) -ne 0 ]] && sudo="sudo"
if ((${#missing[@]})); then
  echo "install-deps: installing ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -qq
  $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
else
  echo "install-deps: Debian packages present"
fi

# ParaView's Python modules (package python3-paraview) unpacked into .tools/paraview-python:
# the package conflicts with python3-vtk9, which libvtk9-dev needs, so it cannot be installed
# beside the build's VTK. pvbatch finds them through PYTHONPATH (paraview/README.md).
pv_dir="$here/.tools/paraview-python"
if ((want_venv)); then
  pv_version=$(dpkg-query -W -f='${Version}' paraview)
  if [[ "$(cat "$pv_dir/.version" 2>/dev/null)" != "$pv_version" ]]; then
    echo "install-deps: unpacking python3-paraview $pv_version into $pv_dir"
    tmp=$(mktemp -d)
    chmod 755 "$tmp"  # apt's download user writes there
    if ! (cd "$tmp" && apt-get download -qq "python3-paraview=$pv_version" 2>/dev/null); then
      $sudo apt-get update -qq
      (cd "$tmp" && apt-get download -qq "python3-paraview=$pv_version")
    fi
    rm -rf "$pv_dir"
    mkdir -p "$pv_dir"
    dpkg -x "$tmp"/python3-paraview_*.deb "$pv_dir"
    echo "$pv_version" > "$pv_dir/.version"
    rm -rf "$tmp"
  fi
fi

# buf, the protobuf linter (make lint-proto), from npm into .tools/.
buf="$here/.tools/node_modules/.bin/buf"
if ((want_venv)) && [[ ! -x "$buf" ]]; then
  echo "install-deps: installing buf (npm @bufbuild/buf)"
  npm install --silent --no-audit --no-fund --prefix "$here/.tools" @bufbuild/buf@1.47.2 >/dev/null
fi

if ((want_venv)); then
  venv="$here/.venv"
  stamp="$venv/.requirements.stamp"
  req="$here/scripts/requirements-dev.txt"
  if [[ ! -x "$venv/bin/python" ]]; then
    python3 -m venv "$venv"
  fi
  if [[ ! -f "$stamp" ]] || ! cmp -s "$req" "$stamp"; then
    "$venv/bin/pip" install -q --upgrade pip
    "$venv/bin/pip" install -q -r "$req"
    cp "$req" "$stamp"
  else
    echo "install-deps: Python environment up to date"
  fi
  # The Python client, editable; reinstalled (stubs regenerated) when its build inputs change.
  client_stamp="$venv/.client-py.stamp"
  client_inputs=$(cat "$here/client-py/pyproject.toml" "$here/client-py/setup.py" \
                      "$here"/proto/actopo/v1/*.proto | sha256sum)
  if [[ ! -f "$client_stamp" ]] || [[ "$(cat "$client_stamp")" != "$client_inputs" ]]; then
    echo "install-deps: installing the Python client (client-py)"
    "$venv/bin/pip" install -q -e "$here/client-py[all]"
    echo "$client_inputs" > "$client_stamp"
  else
    echo "install-deps: Python client up to date"
  fi
fi
