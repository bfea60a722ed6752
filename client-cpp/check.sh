#!/usr/bin/env bash
# The consumer-side check of the C++ client, as a user would go:
#   1. configure and build client-cpp with its tests into BUILD/client;
#   2. install it into BUILD/client-install;
#   3. run its tests (they start actopo-server themselves);
#   4. configure and build client-cpp/examples as a separate project against the installed
#      package (-DCMAKE_PREFIX_PATH=BUILD/client-install) into BUILD/client-examples;
#   5. start an actopo-server and run the examples against it.
#
# Usage: bash client-cpp/check.sh BUILD        (e.g. `bash client-cpp/check.sh build`)
# Environment: JOBS (default 2), ACTOPO_SERVER_BIN / ACTOPO_BENCH_BIN (default
# BUILD/server/cmd/actopo-server, actopo-bench), ACTOPO_DATA_DIR (default ../shared/data beside
# the checkout, else /work/shared/data).
set -euo pipefail

if [[ $# -ne 1 ]]; then
  echo "usage: bash client-cpp/check.sh BUILD_DIR" >&2
  exit 2
fi
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
root=$(dirname "$here")
mkdir -p "$1"
build=$(cd "$1" && pwd)
jobs=${JOBS:-2}
generator=()
if command -v ninja > /dev/null; then generator=(-G Ninja); fi

export ACTOPO_SERVER_BIN=${ACTOPO_SERVER_BIN:-$build/server/cmd/actopo-server}
export ACTOPO_BENCH_BIN=${ACTOPO_BENCH_BIN:-$build/server/cmd/actopo-bench}
if [[ -z ${ACTOPO_DATA_DIR:-} ]]; then
  ACTOPO_DATA_DIR=$root/../shared/data
  [[ -d $ACTOPO_DATA_DIR ]] || ACTOPO_DATA_DIR=/work/shared/data
fi
export ACTOPO_DATA_DIR
start=$SECONDS
step() { echo "== client-cpp/check.sh [$((SECONDS - start)) s]: $*"; }

step "build the library and its tests in $build/client"
cmake -S "$here" -B "$build/client" "${generator[@]}" -DCMAKE_BUILD_TYPE=Release \
  -DACTOPO_CLIENT_BUILD_TESTS=ON > "$build/client-configure.log" ||
  { cat "$build/client-configure.log"; exit 1; }
cmake --build "$build/client" -j "$jobs"

step "install into $build/client-install"
rm -rf "$build/client-install"
cmake --install "$build/client" --prefix "$build/client-install" > /dev/null

step "run the tests"
ctest --test-dir "$build/client" --output-on-failure

step "build the examples against the installed package"
rm -rf "$build/client-examples"
cmake -S "$here/examples" -B "$build/client-examples" "${generator[@]}" \
  -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH="$build/client-install" \
  > "$build/client-examples-configure.log" ||
  { cat "$build/client-examples-configure.log"; exit 1; }
cmake --build "$build/client-examples" -j "$jobs"

if [[ ! -x $ACTOPO_SERVER_BIN ]]; then
  step "no actopo-server at $ACTOPO_SERVER_BIN: examples built, not run"
  exit 0
fi
step "run the examples against a fresh actopo-server"
log=$(mktemp)
env -u ACTOPO_TOKEN "$ACTOPO_SERVER_BIN" --host 127.0.0.1 --port 0 \
  --data-dir "$ACTOPO_DATA_DIR" > "$log" 2>&1 &
server=$!
trap 'kill "$server" 2> /dev/null || true; wait "$server" 2> /dev/null || true; rm -f "$log"' EXIT
target=""
for _ in $(seq 300); do
  target=$(sed -n 's/^actopo-server listening on //p' "$log")
  [[ -n $target ]] && break
  kill -0 "$server" 2> /dev/null || { cat "$log"; echo "actopo-server exited" >&2; exit 1; }
  sleep 0.1
done
[[ -n $target ]] || { cat "$log"; echo "actopo-server did not start" >&2; exit 1; }

out=$("$build/client-examples/critical_points" "$target" sample:jittered:16)
echo "$out"
grep -q '^minimum: [1-9]' <<< "$out"
"$build/client-examples/query_relations" "$target" > /dev/null
"$build/client-examples/stream_batch" "$target" jittered:12 > /dev/null
# A sample is sample:NAME everywhere; stream_batch also takes the bare name above, and a mesh
# argument that names a sample is answered with the exact spelling.
"$build/client-examples/stream_batch" "$target" sample:jittered:12 > /dev/null
out=$("$build/client-examples/critical_points" "$target" fertility_tet.vtu)
grep -q '^minimum: [1-9]' <<< "$out"
if out=$("$build/client-examples/critical_points" "$target" jittered:16 2>&1); then
  echo "critical_points with a bare sample name should fail" >&2
  exit 1
fi
grep -q "load it as sample:jittered:16" <<< "$out" ||
  { echo "$out"; echo "no sample:NAME hint" >&2; exit 1; }
out=$("$build/client-examples/series" "$target" sample:jittered:12 2> /dev/null)
echo "$out"
grep -q '^ 1 height ' <<< "$out"
out=$("$build/client-examples/split_tree" "$target" sample:jittered:16 3)
echo "$out"
grep -q '^region [0-9]*: [1-9][0-9]* vertices, from vertex ' <<< "$out"
# Files of this machine uploaded as their bytes: a .vtu, and a .pvd with the four files it names.
out=$("$build/client-examples/upload_file" "$target" "$ACTOPO_DATA_DIR/fertility_tet.vtu" \
  2> /dev/null)
echo "$out"
grep -q '^fertility_tet.vtu: 14570 vertices, 60948 tetrahedra' <<< "$out"
grep -q '^source: upload:fertility_tet.vtu$' <<< "$out"
out=$("$build/client-examples/upload_file" "$target" \
  "$ACTOPO_DATA_DIR/isabel_series_s2/isabel_series.pvd" 2> /dev/null)
grep -q '^field velocityMag_3 (float64) .* at time 5$' <<< "$out" ||
  { echo "$out"; echo "upload_file: no velocityMag_3 at time 5 from the .pvd" >&2; exit 1; }
step "all passed"
