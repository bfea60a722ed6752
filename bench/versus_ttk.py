#!/usr/bin/env python3
"""Upstream TTK and actopo-bench side by side, in one run, on the same files: for every mesh and
workload, TTK's program and ours for each structure alternate RUNS times (so a drift of the
machine hits all of them), each a whole process under /usr/bin/time. Prints a Markdown table of
medians (min-max) of wall seconds and peak RSS, the ratios to TTK paired run by run, actopo
against our explicit structure, and where our time went (actopo-bench's phases). bench/RESULTS.md
quotes TTK only from this script.

    .venv/bin/python bench/versus_ttk.py --ttk /tmp/ttk/build --runs 3 \\
        --mesh wavelet128.vtu:RTData --mesh part_5M.vtu:velocityMag \\
        --structures explicit,compact,actopo --plot bench/versus_ttk.png
    .venv/bin/python bench/versus_ttk.py --from-json bench/results/versus_ttk.json --plot x.png

Workloads (TTK's side, then ours):
  critical-points         ttkScalarFieldCriticalPointsCmd -t THREADS
  discrete-gradient       bench/ttk_gradient.py (MorseSmaleComplex with only critical points)
  morse-smale             ttkMorseSmaleComplexCmd -t THREADS
  persistence-diagram     ttkPersistenceDiagramCmd -B 2 -t THREADS
  simplified-morse-smale  bench/ttk_chain.py (diagram, 1% threshold, simplification, complex);
                          ours: --algorithm morse-smale --relative-threshold 0.01
  join-tree, split-tree   ttkMergeTreeCmd -T 0 | 1 -t THREADS; ours: --algorithm merge-tree
                          --tree join | split
  contour-tree            ttkContourTreeCmd -t THREADS
Ours run with each structure's defaults (threads from the cores) and without digests, as a user
runs them; --check then runs every structure once more with --digests and fails unless all give
the same result. TTK comes from ../shared/tools/build-ttk.sh with the extra modules
ttkTopologicalSimplification ttkPersistenceDiagram ttkMorseSmaleComplex. The raw runs go to
--json (default bench/results/versus_ttk.json); --from-json prints and plots them again without
running anything.
"""
import argparse
import json
import os
import re
import statistics
import subprocess
import sys
from pathlib import Path

from _plotting import require_matplotlib, save_png

ROOT = Path(__file__).resolve().parents[1]
WORKLOADS = ["critical-points", "discrete-gradient", "morse-smale", "persistence-diagram",
             "simplified-morse-smale", "join-tree", "split-tree", "contour-tree"]
STRUCTURES = ["explicit", "compact", "actopo"]
PHASES = ["load", "partition", "preprocess", "run", "results"]
THRESHOLD = 0.01  # simplified-morse-smale: relative persistence threshold


def ttk_command(ttk: Path, workload: str, path: str, field: str, threads: int) -> list[str]:
    python = ["/usr/bin/python3"]  # TTK's wrappers are built for Debian's Python
    return {
        "critical-points": [str(ttk / "bin/ttkScalarFieldCriticalPointsCmd"), "-i", path, "-a",
                            field, "-t", str(threads), "-o", ""],
        "discrete-gradient": [*python, str(ROOT / "bench/ttk_gradient.py"), path, field,
                              str(threads)],
        "morse-smale": [str(ttk / "bin/ttkMorseSmaleComplexCmd"), "-i", path, "-a", field, "-t",
                        str(threads), "-o", ""],
        "persistence-diagram": [str(ttk / "bin/ttkPersistenceDiagramCmd"), "-i", path, "-a",
                                field, "-B", "2", "-t", str(threads), "-o", ""],
        "simplified-morse-smale": [*python, str(ROOT / "bench/ttk_chain.py"), path, field,
                                   str(THRESHOLD), str(threads)],
        "join-tree": [str(ttk / "bin/ttkMergeTreeCmd"), "-i", path, "-a", field, "-T", "0", "-t",
                      str(threads), "-o", ""],
        "split-tree": [str(ttk / "bin/ttkMergeTreeCmd"), "-i", path, "-a", field, "-T", "1", "-t",
                       str(threads), "-o", ""],
        "contour-tree": [str(ttk / "bin/ttkContourTreeCmd"), "-i", path, "-a", field, "-t",
                         str(threads), "-o", ""],
    }[workload]


def our_command(bench: str, workload: str, path: str, field: str, structure: str,
                extra: list[str]) -> list[str]:
    algorithm = ["--algorithm", workload]
    if workload == "simplified-morse-smale":
        algorithm = ["--algorithm", "morse-smale", "--relative-threshold", str(THRESHOLD)]
    if workload in ("join-tree", "split-tree"):
        algorithm = ["--algorithm", "merge-tree", "--tree", workload.removesuffix("-tree")]
    return [bench, "--mesh", path, "--scalar", field, *algorithm, "--structure", structure,
            "--json", *extra]


def timed(cmd: list[str], env: dict[str, str] | None = None) -> dict:
    """Wall, user and system seconds and peak RSS (MiB) of one whole process; with
    actopo-bench's phases."""
    proc = subprocess.run(["/usr/bin/time", "-f", "TIME %e %M %U %S", *cmd], capture_output=True,
                          text=True, env=env, check=False)
    if proc.returncode != 0:
        sys.exit(f"failed ({proc.returncode}): {' '.join(cmd)}\n{proc.stderr[-2000:]}")
    wall, rss, user, system = re.search(r"TIME ([\d.]+) (\d+) ([\d.]+) ([\d.]+)",
                                        proc.stderr).groups()
    run = {"wall_s": float(wall), "peak_mib": int(rss) / 1024, "user_s": float(user),
           "sys_s": float(system)}
    if proc.stdout.startswith("{"):
        report = json.loads(proc.stdout)
        run["phases_s"] = {k: v for k, v in report["times_s"].items() if k in PHASES}
        run["result"] = report["result"]
    return run


def measure(args, ttk: Path) -> list[dict]:
    env = dict(os.environ, LD_LIBRARY_PATH=str(ttk / "lib"),
               PYTHONPATH=str(ttk / "lib/python3/dist-packages"))
    cases = []
    for spec in args.mesh:
        path, field = spec.rsplit(":", 1)
        for workload in args.workloads:
            case = {"mesh": Path(path).name, "field": field, "workload": workload,
                    "ttk": [], **{s: [] for s in args.structures}}
            for i in range(args.runs):
                case["ttk"].append(timed(ttk_command(ttk, workload, path, field, args.threads),
                                         env))
                for structure in args.structures:
                    case[structure].append(timed(our_command(args.bench, workload, path, field,
                                                             structure, args.extra)))
                print(f"{case['mesh']} {workload}: run {i + 1}/{args.runs}", file=sys.stderr)
            if args.check:
                case["check"] = check(args, workload, path, field)
            cases.append(case)
    return cases


def check(args, workload: str, path: str, field: str) -> str:
    """Every structure's result with digests: they must be the same."""
    results = {s: timed(our_command(args.bench, workload, path, field, s,
                                    [*args.extra, "--digests"]))["result"]
               for s in args.structures}
    first = results[args.structures[0]]
    differing = [s for s, r in results.items() if r != first]
    if differing:
        sys.exit(f"{Path(path).name} {workload}: {differing} differ from "
                 f"{args.structures[0]}:\n{json.dumps(results, indent=1)[:4000]}")
    return "same result with digests on " + ", ".join(args.structures)


def spread(values: list[float], digits: int = 2) -> str:
    return (f"{statistics.median(values):.{digits}f} "
            f"({min(values):.{digits}f}-{max(values):.{digits}f})")


def ratio(case: dict, ours: str, base: str, key: str) -> list[float]:
    """ours/base per run: run i of each was measured back to back."""
    return [o[key] / b[key] for o, b in zip(case[ours], case[base], strict=True)]


def print_tables(cases: list[dict], structures: list[str]) -> None:
    head = " | ".join(f"ours {s} s / MiB" for s in structures)
    print(f"| mesh | workload | TTK s / MiB | {head} | {structures[-1]}/TTK time | "
          f"{structures[-1]}/TTK memory |" + (" actopo/explicit time |"
                                              if {"actopo", "explicit"} <= set(structures)
                                              else ""))
    print("|---|---|---|" + "---|" * len(structures) + "---|---|" +
          ("---|" if {"actopo", "explicit"} <= set(structures) else ""))
    for c in cases:
        cells = [f"{spread([r['wall_s'] for r in c[s]])} / "
                 f"{statistics.median(r['peak_mib'] for r in c[s]):.0f}"
                 for s in ["ttk", *structures]]
        last = structures[-1]
        row = [c["mesh"], c["workload"], *cells, f"{spread(ratio(c, last, 'ttk', 'wall_s'))}x",
               f"{statistics.median(ratio(c, last, 'ttk', 'peak_mib')):.2f}x"]
        if {"actopo", "explicit"} <= set(structures):
            row.append(f"{spread(ratio(c, 'actopo', 'explicit', 'wall_s'))}x")
        print("| " + " | ".join(row) + " |")
    print_cpu_table(cases, structures)
    print("\nWhere our time went (actopo-bench's phases, medians, seconds):\n")
    print("| mesh | workload | structure | " + " | ".join(PHASES) + " |")
    print("|---|---|---|" + "---|" * len(PHASES))
    for c in cases:
        for s in structures:
            phases = [statistics.median(r["phases_s"].get(p, 0.0) for r in c[s]) for p in PHASES]
            print(f"| {c['mesh']} | {c['workload']} | {s} | " +
                  " | ".join(f"{p:.2f}" for p in phases) + " |")
    checks = [f"{c['mesh']} {c['workload']}: {c['check']}" for c in cases if "check" in c]
    if checks:
        print("\n" + "\n".join(checks))


def print_cpu_table(cases: list[dict], structures: list[str]) -> None:
    """User and system seconds beside the wall time: the system part (first touch of memory,
    page faults) drifts on a shared machine from hour to hour and weighs with the footprint, so
    a TTK wall time that moved with its system time alone shows here. Runs recorded before these
    were kept (no user_s) are left out."""
    kept = [c for c in cases if all("user_s" in r for s in ["ttk", *structures] for r in c[s])]
    if not kept:
        return
    print("\nCPU time (medians, seconds: user + system):\n")
    print("| mesh | workload | TTK | " + " | ".join(f"ours {s}" for s in structures) + " |")
    print("|---|---|---|" + "---|" * len(structures))
    for c in kept:
        cells = [f"{statistics.median(r['user_s'] for r in c[s]):.2f} + "
                 f"{statistics.median(r['sys_s'] for r in c[s]):.2f}"
                 for s in ["ttk", *structures]]
        print(f"| {c['mesh']} | {c['workload']} | " + " | ".join(cells) + " |")


def plot(cases: list[dict], structures: list[str], path: str) -> None:
    require_matplotlib()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    meshes = list(dict.fromkeys(c["mesh"] for c in cases))
    fig, axes = plt.subplots(2, len(meshes), figsize=(6.5 * len(meshes), 7), squeeze=False)
    series = ["ttk", *structures]
    width = 0.8 / len(series)
    for col, mesh in enumerate(meshes):
        mine = [c for c in cases if c["mesh"] == mesh]
        for row, (key, label) in enumerate((("wall_s", "whole process, s"),
                                            ("peak_mib", "peak RSS, MiB"))):
            ax = axes[row][col]
            for k, s in enumerate(series):
                values = [statistics.median(r[key] for r in c[s]) for c in mine]
                xs = [i + (k - (len(series) - 1) / 2) * width for i in range(len(mine))]
                ax.bar(xs, values, width, label="TTK" if s == "ttk" else f"ours, {s}")
            ax.set_xticks(range(len(mine)))
            ax.set_xticklabels([c["workload"].replace("-", "-\n", 1) for c in mine], fontsize=8)
            ax.set_ylabel(label)
            if row == 0:
                ax.set_title(mesh)
                ax.legend(fontsize=8)
    fig.suptitle("Upstream TTK and actopo-bench in one run (medians)")
    fig.tight_layout()
    save_png(fig, path, dpi=100)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ttk", help="TTK's build directory (bin/, lib/)")
    ap.add_argument("--mesh", action="append", default=[], help="FILE:FIELD, repeatable")
    ap.add_argument("--workloads", default=",".join(WORKLOADS),
                    help=f"comma-separated, of {', '.join(WORKLOADS)}")
    ap.add_argument("--structures", default="actopo",
                    help="ours, comma-separated (explicit, compact, actopo); ratios to TTK "
                    "are the last one's")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 2, help="TTK's threads")
    ap.add_argument("--check", action="store_true",
                    help="also run each structure once with --digests: the results must agree")
    ap.add_argument("--bench", default=str(ROOT / "build/server/cmd/actopo-bench"))
    ap.add_argument("--json", default=str(ROOT / "bench/results/versus_ttk.json"),
                    help="where the raw runs go")
    ap.add_argument("--from-json", help="print (and --plot) the runs of an earlier --json")
    ap.add_argument("--plot", help="PNG: time and peak memory per workload, per mesh")
    ap.add_argument("extra", nargs="*", help="after --: more actopo-bench flags")
    args = ap.parse_args()
    args.workloads = args.workloads.split(",")
    args.structures = args.structures.split(",")
    if args.plot:
        require_matplotlib()
    unknown = sorted(set(args.workloads) - set(WORKLOADS)) + \
        sorted(set(args.structures) - set(STRUCTURES))
    if unknown:
        sys.exit(f"unknown workload or structure: {', '.join(unknown)}")
    if args.from_json:
        saved = json.loads(Path(args.from_json).read_text())
        cases, args.structures = saved["cases"], saved["structures"]
    else:
        if not args.ttk or not args.mesh:
            sys.exit("give --ttk DIR and at least one --mesh FILE:FIELD (or --from-json)")
        cases = measure(args, Path(args.ttk))
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(
            {"structures": args.structures, "runs": args.runs, "threads": args.threads,
             "cases": cases}, indent=1))
        print(f"wrote {args.json}", file=sys.stderr)
    print_tables(cases, args.structures)
    if args.plot:
        plot(cases, args.structures, args.plot)


if __name__ == "__main__":
    main()
