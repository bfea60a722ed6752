#!/usr/bin/env python3
"""Persistence diagram and simplified Morse-Smale complex, side by side with upstream TTK in one
run: the two programs alternate on the same file, whole process under /usr/bin/time, RUNS times
each; prints a Markdown table of medians (min-max) of wall seconds and peak RSS, with our/TTK
ratios. TTK's side: ttkPersistenceDiagramCmd for the diagram; bench/ttk_chain.py (PersistenceDiagram
-> threshold -> TopologicalSimplification -> MorseSmaleComplex, TTK's filters in one Python
process) for the simplified complex. Ours: actopo-bench with the structure's defaults.

    python3 bench/persistence_vs_ttk.py --ttk /tmp/ttk/build --runs 3 \\
        --mesh wavelet128.vtu:RTData --mesh part_5M.vtu:velocityMag [--chain-threshold 0.01]

TTK is built by ../shared/tools/build-ttk.sh with the extra modules ttkTopologicalSimplification
ttkPersistenceDiagram ttkMorseSmaleComplex (their Python wrappers come with them).
"""
import argparse
import json
import os
import re
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def timed(cmd, env=None):
    """Wall seconds and peak RSS (MiB) of one whole process, and its stdout."""
    proc = subprocess.run(["/usr/bin/time", "-f", "TIME %e %M", *cmd], capture_output=True,
                          text=True, env=env, check=False)
    if proc.returncode != 0:
        sys.exit(f"failed ({proc.returncode}): {' '.join(cmd)}\n{proc.stderr[-2000:]}")
    wall, rss = re.search(r"TIME ([\d.]+) (\d+)", proc.stderr).groups()
    return float(wall), int(rss) / 1024, proc.stdout


def summary(values):
    return statistics.median(values), min(values), max(values)


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ttk", required=True, help="TTK's build directory (bin/, lib/)")
    ap.add_argument("--mesh", action="append", required=True, help="FILE:FIELD, repeatable")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--structure", default="actopo")
    ap.add_argument("--chain-threshold", type=float, default=0.01,
                    help="relative persistence threshold of the simplified Morse-Smale chain")
    ap.add_argument("--no-chain", action="store_true", help="only the persistence diagram")
    ap.add_argument("--bench", default=str(ROOT / "build/server/cmd/actopo-bench"))
    args = ap.parse_args()
    ttk = Path(args.ttk)
    env = dict(os.environ, LD_LIBRARY_PATH=str(ttk / "lib"),
               PYTHONPATH=str(ttk / "lib/python3/dist-packages"))
    rows = []
    for spec in args.mesh:
        path, field = spec.rsplit(":", 1)
        cases = [("persistence diagram",
                  [str(ttk / "bin/ttkPersistenceDiagramCmd"), "-i", path, "-a", field, "-B", "2",
                   "-t", "2", "-o", ""],
                  [args.bench, "--mesh", path, "--scalar", field, "--algorithm",
                   "persistence-diagram", "--structure", args.structure, "--json"])]
        if not args.no_chain:
            cases.append((f"simplified Morse-Smale (t = {args.chain_threshold:g})",
                          ["/usr/bin/python3", str(ROOT / "bench/ttk_chain.py"), path, field,
                           str(args.chain_threshold)],
                          [args.bench, "--mesh", path, "--scalar", field, "--algorithm",
                           "morse-smale", "--relative-threshold", str(args.chain_threshold),
                           "--structure", args.structure, "--json"]))
        for name, ttk_cmd, ours_cmd in cases:
            ttk_runs, our_runs, ratios = [], [], []
            for _ in range(args.runs):  # alternating, so a drift of the machine hits both
                t = timed(ttk_cmd, env)
                o = timed(ours_cmd)
                ttk_runs.append(t[:2])
                our_runs.append(o[:2])
                ratios.append(o[0] / t[0])
                result = json.loads(o[2])["result"]
            rows.append((Path(path).name, name, ttk_runs, our_runs, ratios, result))
            print(f"{Path(path).name} {name}: done", file=sys.stderr)
    print("| mesh | workload | TTK wall s | TTK peak MiB | ours wall s | ours peak MiB "
          "| time ratio | memory ratio |")
    print("|---|---|---|---|---|---|---|---|")
    for mesh, name, t, o, ratios, _ in rows:
        tw, tm = summary([r[0] for r in t]), summary([r[1] for r in t])
        ow, om = summary([r[0] for r in o]), summary([r[1] for r in o])
        rw = summary(ratios)
        print(f"| {mesh} | {name} | {tw[0]:.2f} ({tw[1]:.2f}-{tw[2]:.2f}) | {tm[0]:.0f} | "
              f"{ow[0]:.2f} ({ow[1]:.2f}-{ow[2]:.2f}) | {om[0]:.0f} | {rw[0]:.2f}x "
              f"({rw[1]:.2f}-{rw[2]:.2f}) | {om[0] / tm[0]:.2f}x |")
    for mesh, _, *_, result in rows:
        if "pairs_sha256" in result:
            print(f"\n{mesh}: {result['pairs']} pairs, pairs_sha256 {result['pairs_sha256']}")


if __name__ == "__main__":
    main()
