#!/usr/bin/env bash
# Runs every fuzz target for SECONDS each, starting from its seed corpus (fuzz/corpus/<target>)
# plus what earlier runs found (BUILD/corpus/<target>), and prints executions and coverage.
# A crash, a sanitizer report, a timeout or an out-of-memory leaves the input in
# BUILD/artifacts/ and fails the run.
#   bash fuzz/run.sh build-fuzz 60
set -uo pipefail
build=${1:?build directory}
seconds=${2:-60}
here=$(cd "$(dirname "$0")" && pwd)
failed=0
mkdir -p "$build/artifacts"
for target in upload_fuzzer mesh_file_fuzzer partition_fuzzer request_fuzzer; do
  name=${target%_fuzzer}
  work="$build/corpus/$name"
  mkdir -p "$work"
  log="$build/$target.log"
  "$build/fuzz/$target" "$work" "$here/corpus/$name" -max_total_time="$seconds" -timeout=20 \
    -rss_limit_mb=3072 -print_final_stats=1 -artifact_prefix="$build/artifacts/$name-" \
    >"$log" 2>&1
  status=$?
  done_line=$(grep -E "^#[0-9]+ +DONE" "$log" | tail -1)
  runs=$(grep -E "^stat::number_of_executed_units" "$log" | awk '{print $2}')
  echo "fuzz: $target: exit $status, ${runs:-?} executions in ${seconds} s; ${done_line:-no final line}"
  if ((status != 0)); then
    failed=1
    grep -E "ERROR|SUMMARY|Test unit written" "$log" | head -5
  fi
done
exit $failed
