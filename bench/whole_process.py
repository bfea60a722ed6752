#!/usr/bin/env python3
"""Whole-process benchmark: what a user waits for, start to exit, on one mesh.

Runs actopo-bench for every structure and algorithm RUNS times under /usr/bin/time, and prints a
Markdown table of medians: wall seconds and peak RSS of the whole process (the operating system's
figures), with actopo-bench's own phase breakdown (load, partition, preprocess, run, results) and
the consumers' wait. Raw JSON goes to bench/results/; with --plot PNG a bar chart of time and peak
memory per structure and algorithm is written too (needs matplotlib).

    python3 bench/whole_process.py --mesh /path/wavelet128.vtu [--runs 3] [--plot bench/x.png]
    python3 bench/whole_process.py --mesh F.vtu --structures actopo --algorithms critical-points
    python3 bench/whole_process.py --sample jittered:256 --structures actopo --runs 1

Default threads come from the cores (DefaultThreadPlan); extra actopo-bench flags go after --.
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
STRUCTURES = ["explicit", "compact", "actopo"]
ALGORITHMS = ["critical-points", "discrete-gradient", "morse-smale", "topo-relations"]


def run_once(bench, source, structure, algorithm, extra):
    cmd = ["/usr/bin/time", "-f", "TIME %e %M", str(bench), *source,
           "--structure", structure, "--algorithm", algorithm, "--json", *extra]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=True)
    wall, rss_kib = re.search(r"TIME ([\d.]+) (\d+)", proc.stderr).groups()
    report = json.loads(proc.stdout)
    report["process"] = {"wall_s": float(wall), "peak_rss_mib": int(rss_kib) / 1024}
    return report


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--mesh", help="mesh file")
    where.add_argument("--sample", help="built-in sample, e.g. jittered:256")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--structures", nargs="+", default=STRUCTURES)
    parser.add_argument("--algorithms", nargs="+", default=ALGORITHMS)
    parser.add_argument("--build", default=os.environ.get("ACTOPO_BUILD", ROOT / "build"))
    parser.add_argument("--plot", help="write a PNG chart here")
    parser.add_argument("extra", nargs="*", help="more actopo-bench flags, after --")
    args = parser.parse_args()
    bench = Path(args.build) / "server/cmd/actopo-bench"
    source = ["--mesh", args.mesh] if args.mesh else ["--sample", args.sample]
    name = Path(args.mesh).name if args.mesh else args.sample
    out = ROOT / "bench/results"
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for algorithm in args.algorithms:
        for structure in args.structures:
            runs = [run_once(bench, source, structure, algorithm, args.extra)
                    for _ in range(args.runs)]
            tag = f"{Path(name).stem.replace(':', '')}_{structure}_{algorithm}"
            (out / f"whole_{tag}.json").write_text(json.dumps(runs, indent=1))
            med = lambda f: statistics.median(f(r) for r in runs)  # noqa: E731
            rows.append({
                "algorithm": algorithm, "structure": structure,
                "config": runs[0]["config"],
                "wall_s": med(lambda r: r["process"]["wall_s"]),
                "wall_range": (min(r["process"]["wall_s"] for r in runs),
                               max(r["process"]["wall_s"] for r in runs)),
                "rss_mib": med(lambda r: r["process"]["peak_rss_mib"]),
                **{k: med(lambda r, k=k: r["times_s"][k])
                   for k in ["load", "partition", "preprocess", "run", "results"]},
                "wait_s": med(lambda r: r["engine"]["wait_s"]),
                "tets": runs[0]["mesh"]["tetrahedra"],
            })
    print(f"{name}: {rows[0]['tets']:,} tetrahedra, median of {args.runs} runs, "
          f"whole process (wall s, peak RSS MiB by /usr/bin/time)")
    print()
    print("| algorithm | structure | C / P | wall s (min-max) | peak RSS MiB | load | partition "
          "| preprocess | run | results | wait s |")
    print("|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        c = r["config"]
        threads = f"{c['consumers']} / {c['producers']}" if c["producers"] else f"{c['consumers']}"
        lo, hi = r["wall_range"]
        print(f"| {r['algorithm']} | {r['structure']} | {threads} | {r['wall_s']:.2f} "
              f"({lo:.2f}-{hi:.2f}) | {r['rss_mib']:.0f} | {r['load']:.2f} | {r['partition']:.2f} "
              f"| {r['preprocess']:.2f} | {r['run']:.2f} | {r['results']:.2f} | {r['wait_s']:.2f} |")
    if args.plot:
        plot(rows, args.plot, name)


def plot(rows, path, title):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    algorithms = list(dict.fromkeys(r["algorithm"] for r in rows))
    structures = list(dict.fromkeys(r["structure"] for r in rows))
    fig, (ax_t, ax_m) = plt.subplots(1, 2, figsize=(12, 4.5))
    width = 0.8 / len(structures)
    phases = ["load", "partition", "preprocess", "run", "results"]
    colors = ["#888888", "#c9a227", "#6a9fb5", "#2c7bb6", "#d7191c"]
    for s_index, structure in enumerate(structures):
        for a_index, algorithm in enumerate(algorithms):
            r = next(x for x in rows if x["algorithm"] == algorithm and x["structure"] == structure)
            x = a_index + (s_index - (len(structures) - 1) / 2) * width
            bottom = 0.0
            for phase, color in zip(phases, colors):
                ax_t.bar(x, r[phase], width * 0.9, bottom=bottom, color=color,
                         label=phase if s_index == 0 and a_index == 0 else None)
                bottom += r[phase]
            ax_t.text(x, bottom, structure[0].upper(), ha="center", va="bottom", fontsize=7)
            ax_m.bar(x, r["rss_mib"], width * 0.9, color=f"C{s_index}",
                     label=structure if a_index == 0 else None)
    ax_t.set_ylim(0, 1.08 * max(sum(r[p] for p in phases) for r in rows))  # room for the labels
    for ax, label in [(ax_t, "seconds (phases, whole process)"), (ax_m, "peak RSS, MiB")]:
        ax.set_xticks(range(len(algorithms)), algorithms, rotation=15)
        ax.set_ylabel(label)
        ax.legend(fontsize=8)
    ax_t.set_title(f"time per phase on {title} (E explicit, C compact, A actopo)", fontsize=9)
    ax_m.set_title(f"peak memory on {title}", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"\nwrote {path}", file=sys.stderr)


if __name__ == "__main__":
    main()
