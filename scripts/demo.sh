#!/usr/bin/env bash
# make demo: start actopo-server on a free port, load a built-in sample, run critical points and
# the Morse-Smale complex through the Python CLI, ask some relations, print statistics, stop.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
build=${BUILD:-$here/build}
sample=${DEMO_SAMPLE:-wavelet:48}
# The structures compared on a mesh where their costs differ visibly (4.3M tetrahedra).
compare_sample=${DEMO_COMPARE_SAMPLE:-wavelet:96}
data_dir=${DATA_DIR:-$here/../shared/data}
[[ -d "$data_dir" ]] || data_dir=$(mktemp -d)
actopo="$here/.venv/bin/actopo"

log=$(mktemp)
"$build/server/cmd/actopo-server" --host 127.0.0.1 --port 0 --data-dir "$data_dir" >"$log" 2>&1 &
server=$!
trap 'kill $server 2>/dev/null; wait $server 2>/dev/null; rm -f "$log"' EXIT
for _ in $(seq 100); do
  grep -q "listening on" "$log" && break
  sleep 0.1
done
target=$(sed -n 's/.*listening on //p' "$log")
[[ -n "$target" ]] || { cat "$log"; echo "demo: the server did not start"; exit 1; }
export ACTOPO_SERVER=$target
step() { printf '\n== %s\n' "$*"; }

step "actopo-server on $target"
"$actopo" info

step "load the built-in sample $sample (ParaView's Wavelet, tetrahedralized)"
mesh=$("$actopo" load "sample:$sample" --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["mesh_id"])')
"$actopo" meshes

step "critical points (TTK ScalarFieldCriticalPoints) on the actopo structure"
"$actopo" run --mesh-id "$mesh" --algorithm critical-points --structure actopo

step "Morse-Smale complex (TTK MorseSmaleComplex 3D) on the actopo structure"
"$actopo" run --mesh-id "$mesh" --algorithm morse-smale --structure actopo

step "persistence diagram (TTK PersistenceDiagram, Discrete Morse Sandwich), pairs per type"
"$actopo" run --mesh-id "$mesh" --algorithm persistence-diagram --structure actopo

step "Morse-Smale complex after simplifying away the pairs below 5% of the range"
"$actopo" run --mesh-id "$mesh" --algorithm morse-smale --structure actopo \
  --param relative_threshold=0.05

step "split tree (TTK MergeTree) of the field simplified at 5% of its range: its largest regions"
"$actopo" run --mesh-id "$mesh" --algorithm merge-tree --tree split --structure actopo \
  --param relative_threshold=0.05
"$here/.venv/bin/python" - "$mesh" <<'PY'
import sys
import actopo
with actopo.Client() as client, client.open_session(sys.argv[1], structure="actopo") as session:
    tree = session.run("merge-tree", parameters={"tree": "split", "relative_threshold": "0.05"}).tree
    print(f"{len(tree.nodes)} nodes, {len(tree.arcs)} arcs; the largest regions:")
    for arc in tree.largest_regions(5):
        up, down = tree.arcs.up[arc], tree.arcs.down[arc]
        print(f"  arc {arc}: {tree.arcs.region_size[arc]} vertices between vertex "
              f"{tree.nodes.vertex[down]} ({tree.nodes.scalar[down]:.2f}) and vertex "
              f"{tree.nodes.vertex[up]} ({tree.nodes.scalar[up]:.2f})")
PY

if [[ -f "$data_dir/isabel_series_s2_tet.vtu" ]]; then
  series=isabel_series_s2_tet.vtu
  step "a time series: the 12 Hurricane Isabel members on one mesh, each member's persistence diagram"
  "$actopo" run --mesh "$series" persistence-diagram --scalars all --structure actopo

  step "the 12 x 12 Wasserstein-2 and bottleneck distances between the members' diagrams (exact)"
  "$actopo" run --mesh "$series" diagram-distance --scalars all --structure actopo

  step "the three groups of the series, by average linkage of the Wasserstein distances"
  "$here/.venv/bin/python" - "$series" <<'PY'
import sys
import actopo
with actopo.Client() as client:
    mesh = client.load_mesh(sys.argv[1])
    with client.open_session(mesh, structure="actopo") as session:
        matrix = session.distance_matrix("all")
    for group in sorted(set(matrix.groups(3))):
        members = [f for f, g in zip(matrix.fields, matrix.groups(3), strict=True) if g == group]
        print(f"group {group}: {', '.join(members)}")
    client.delete_mesh(mesh)
PY
fi

step "relation queries on a session that outlives the commands: the star of vertex 0, the triangles around edge (0,1), vertex 7 on the boundary?"
session=$("$actopo" open "$mesh" --structure actopo --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["session_id"])')
"$actopo" relation --session "$session" vertex_star 0
"$actopo" relation --session "$session" --vertices edge_triangles 0,1
"$actopo" relation --session "$session" vertex_on_boundary 7

step "that session's statistics: its three relation queries, their engine requests, its memory"
"$actopo" stats --session "$session"
"$actopo" close "$session"

step "the three structures on the same jobs on $compare_sample: what a job costs, time and memory"
"$actopo" compare --sample "$compare_sample" --algorithm critical-points
"$actopo" compare --sample "$compare_sample" --algorithm morse-smale
