#!/usr/bin/env bash
# Structure comparison: explicit, compact and actopo (P = 1 and 2) on one algorithm, median of
# RUNS runs each. Prints a Markdown table; raw JSON goes to bench/results/ (not committed).
#   bash bench/compare_structures.sh [--algorithm NAME] [SAMPLE_OR_FILE ...]
#   (default inputs: jittered:96, ~5.1M tetrahedra, and ../shared/data/isabel02_s2_tet.vtu)
set -euo pipefail
cd "$(dirname "$0")/.."
bench=build/server/cmd/actopo-bench
runs=${RUNS:-3}
algorithm=topo-relations
if [[ "${1:-}" == "--algorithm" ]]; then algorithm=$2; shift 2; fi
out=bench/results
mkdir -p "$out"
inputs=("$@")
if [[ ${#inputs[@]} -eq 0 ]]; then
  inputs=(jittered:96)
  for d in ../shared/data /work/shared/data; do
    [[ -f $d/isabel02_s2_tet.vtu ]] && { inputs+=("$d/isabel02_s2_tet.vtu"); break; }
  done
fi
configs=("explicit" "compact" "actopo --producers 1" "actopo --producers 2")

for input in "${inputs[@]}"; do
  if [[ -f "$input" ]]; then src=(--mesh "$input"); else src=(--sample "$input"); fi
  tag=$(basename "$input" | tr ':/.' '___')
  for config in "${configs[@]}"; do
    ctag=$(echo "$config" | tr ' -' '__')
    for ((i = 1; i <= runs; i++)); do
      # shellcheck disable=SC2086
      "$bench" "${src[@]}" --algorithm "$algorithm" --structure $config --json \
        > "$out/${algorithm}_${tag}_${ctag}_$i.json"
    done
  done
done

py=python3
[[ -x .venv/bin/python ]] && py=.venv/bin/python
$py - "$out" "$algorithm" "$runs" "${inputs[@]}" -- "${configs[@]}" <<'PY'
import json, os, statistics, sys
args = sys.argv[1:]
out, algorithm, runs = args[0], args[1], int(args[2])
sep = args.index("--")
inputs, configs = args[3:sep], args[sep + 1:]
print(f"{algorithm}, median of {runs} runs")
print()
print("| mesh | tets | structure | partition s | preprocess s | run s | pre+run s | wait s | hits/requests | peak RSS MiB | structure MiB | buffer peak MiB |")
print("|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
for inp in inputs:
    tag = os.path.basename(inp).replace(":", "_").replace("/", "_").replace(".", "_")
    for config in configs:
        ctag = config.replace(" ", "_").replace("-", "_")
        rs = [json.load(open(f"{out}/{algorithm}_{tag}_{ctag}_{i}.json")) for i in range(1, runs + 1)]
        med = lambda f: statistics.median(f(r) for r in rs)
        e = rs[0]["engine"]
        hit = f"{e['hits']}/{e['requests']}" if e["requests"] else "-"
        print(f"| {os.path.basename(inp)} | {rs[0]['mesh']['tetrahedra']:,} | {config.replace('--producers ', 'P=')} | "
              f"{med(lambda r: r['times_s']['partition']):.2f} | {med(lambda r: r['times_s']['preprocess']):.2f} | "
              f"{med(lambda r: r['times_s']['run']):.2f} | "
              f"{med(lambda r: r['times_s']['preprocess'] + r['times_s']['run']):.2f} | "
              f"{med(lambda r: r['engine']['wait_s']):.2f} | {hit} | "
              f"{med(lambda r: r['memory']['peak_rss_bytes']) / 2**20:.0f} | "
              f"{med(lambda r: r['memory']['structure_bytes']) / 2**20:.0f} | "
              f"{med(lambda r: r['memory']['buffer_peak_bytes']) / 2**20:.0f} |")
PY
