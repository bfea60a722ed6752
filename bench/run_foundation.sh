#!/usr/bin/env bash
# Foundation benchmark: explicit vs compact on topo-relations, median of RUNS runs each, and the
# block relation throughput. Prints a Markdown table; raw JSON goes to bench/results/.
#   bash bench/run_foundation.sh [SAMPLE_OR_FILE ...]   (default: jittered:96, ~5.1M tetrahedra)
set -euo pipefail
cd "$(dirname "$0")/.."
bench=build/server/cmd/actopo-bench
runs=${RUNS:-3}
out=bench/results
mkdir -p "$out"
inputs=("$@")
[[ ${#inputs[@]} -eq 0 ]] && inputs=(jittered:96)
py=python3
[[ -x .venv/bin/python ]] && py=.venv/bin/python

for input in "${inputs[@]}"; do
  if [[ -f "$input" ]]; then source_flag=(--mesh "$input"); else source_flag=(--sample "$input"); fi
  tag=$(basename "$input" | tr ':/' '__')
  for structure in explicit compact; do
    for ((i = 1; i <= runs; i++)); do
      "$bench" "${source_flag[@]}" --algorithm topo-relations --structure "$structure" --json \
        > "$out/foundation_${tag}_${structure}_$i.json"
    done
  done
done

$py - "$out" "${inputs[@]}" <<'PY'
import json, statistics, sys, os
out, inputs = sys.argv[1], sys.argv[2:]
print("| mesh | tets | structure | partition s | preprocess s | run s | wait s | peak RSS MiB | structure MiB |")
print("|---|---:|---|---:|---:|---:|---:|---:|---:|")
for inp in inputs:
    tag = os.path.basename(inp).replace(":", "_").replace("/", "_")
    for s in ("explicit", "compact"):
        runs = []
        i = 1
        while os.path.exists(f"{out}/foundation_{tag}_{s}_{i}.json"):
            runs.append(json.load(open(f"{out}/foundation_{tag}_{s}_{i}.json"))); i += 1
        med = lambda f: statistics.median(f(r) for r in runs)
        print(f"| {inp} | {runs[0]['mesh']['tetrahedra']:,} | {s} | {med(lambda r: r['times_s']['partition']):.2f} | "
              f"{med(lambda r: r['times_s']['preprocess']):.2f} | {med(lambda r: r['times_s']['run']):.2f} | "
              f"{med(lambda r: r['engine']['wait_s']):.2f} | {med(lambda r: r['memory']['peak_rss_bytes'])/2**20:.0f} | "
              f"{med(lambda r: r['memory']['structure_bytes'])/2**20:.0f} |")
PY
echo
build/server/core/block_relations_benchmark --benchmark_min_time=0.5 2>/dev/null | \
  awk '/BM_/ {print}' | tee "$out/block_relations_benchmark.txt"
