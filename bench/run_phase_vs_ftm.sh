#!/bin/bash
# The trees' run phase beside TTK's FTM alone, in one run, alternating: TTK's own timer
# ("[FTMTree] Total" at -d 3, which starts after TTK has read the file and built its
# triangulation's edges and VV) against actopo-bench's `times_s.run` on explicit and actopo.
#
#   bench/run_phase_vs_ftm.sh TTK_BUILD ROUNDS MESH.vtu:FIELD [MESH.vtu:FIELD ...]
#   bench/run_phase_vs_ftm.sh /tmp/ttk/build 3 wavelet128.vtu:RTData part_5M.vtu:velocityMag
#
# TTK_BUILD comes from ../shared/tools/build-ttk.sh with `ttkMergeTree ttkContourTree`. Prints
# one line per round; quote medians (FTM's timer moves 1.5x from run to run). ACTOPO_BENCH names
# another actopo-bench (default: build/server/cmd/actopo-bench).
set -euo pipefail
if [ $# -lt 3 ]; then
  sed -n 2,11p "$0"
  exit 2
fi
ttk=$1 rounds=$2
shift 2
here=$(cd "$(dirname "$0")/.." && pwd)
bench=${ACTOPO_BENCH:-$here/build/server/cmd/actopo-bench}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
export LD_LIBRARY_PATH=$ttk/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}

ftm_total() {  # TTK's command line -> its FTMTree Total in seconds
  "$@" -d 3 -o "$out/ttk" 2>&1 | sed 's/\x1b\[[0-9;]*m//g' | grep '\[FTMTree\] Total' |
    grep -o '\[[0-9.]*s' | tr -d '[s'
}
our_run() {  # structure, actopo-bench flags -> times_s.run
  local structure=$1
  shift
  "$bench" --structure "$structure" --json "$@" |
    python3 -c 'import json, sys; print(round(json.load(sys.stdin)["times_s"]["run"], 3))'
}

for spec in "$@"; do
  mesh=${spec%:*} field=${spec##*:}
  for tree in join contour; do
    if [ "$tree" = join ]; then
      ttk_cmd=("$ttk/bin/ttkMergeTreeCmd" -T 0)
      ours=(--algorithm merge-tree)
    else
      ttk_cmd=("$ttk/bin/ttkContourTreeCmd")
      ours=(--algorithm contour-tree)
    fi
    for round in $(seq "$rounds"); do
      ftm=$(ftm_total "${ttk_cmd[@]}" -i "$mesh" -a "$field" -t 2)
      e=$(our_run explicit --mesh "$mesh" --scalar "$field" "${ours[@]}")
      a=$(our_run actopo --mesh "$mesh" --scalar "$field" "${ours[@]}")
      echo "$(basename "$mesh") $tree round $round: FTM $ftm explicit $e actopo $a"
    done
  done
done
