#!/usr/bin/env python3
"""Whole-process benchmark: what a user waits for, start to exit, on one mesh.

Runs actopo-bench for every structure and algorithm RUNS times under /usr/bin/time, and prints a
Markdown table of medians: wall seconds and peak RSS of the whole process (the operating system's
figures), with actopo-bench's own phase breakdown (load, partition, preprocess, run, results) and
the consumers' wait. Raw JSON goes to bench/results/; with --plot PNG a figure is written too
(needs matplotlib, in .venv): time per phase, peak memory, and the consumers' wait as a share of
the run phase (actopo, with compact's time computing its own misses beside it).

    python3 bench/whole_process.py --mesh /path/wavelet128.vtu [--runs 3] [--plot bench/x.png]
    python3 bench/whole_process.py --mesh F.vtu --structures actopo --algorithms critical-points
    python3 bench/whole_process.py --sample jittered:256 --structures actopo --runs 1
    .venv/bin/python bench/whole_process.py --mesh wavelet128.vtu --from-results \\
        --plot bench/wavelet128_whole_process.png

--from-results reads the JSON an earlier run left in bench/results/ (whole_<mesh>_<structure>_
<algorithm>.json, the mesh named as when it was run; its directory does not matter) instead of
running anything; combinations without a file are skipped.

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

from _plotting import require_matplotlib, save_png

ROOT = Path(__file__).resolve().parents[1]
STRUCTURES = ["explicit", "compact", "actopo"]
ALGORITHMS = ["critical-points", "discrete-gradient", "morse-smale", "topo-relations"]
PHASES = ["load", "partition", "preprocess", "run", "results"]


def run_once(bench, source, structure, algorithm, extra):
    cmd = ["/usr/bin/time", "-f", "TIME %e %M", str(bench), *source,
           "--structure", structure, "--algorithm", algorithm, "--json", *extra]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=True)
    wall, rss_kib = re.search(r"TIME ([\d.]+) (\d+)", proc.stderr).groups()
    report = json.loads(proc.stdout)
    report["process"] = {"wall_s": float(wall), "peak_rss_mib": int(rss_kib) / 1024}
    return report


def wait_share(report):
    """The consumers' wait over their time in the run phase (C consumers x run seconds), and
    each consumer's own share (actopo reports them; compact only the sum)."""
    run = report["times_s"]["run"]
    consumers = report["config"]["consumers"]
    if run <= 0 or consumers <= 0:
        return 0.0, []
    engine = report["engine"]
    return (engine["wait_s"] / (consumers * run),
            [c["wait_s"] / run for c in engine.get("consumers", [])])


def summarize(runs, algorithm, structure):
    """One table row: medians over the runs of one structure and algorithm."""
    def med(f):
        return statistics.median(f(r) for r in runs)
    shares = [wait_share(r) for r in runs]
    per_consumer = [statistics.median(s[1][i] for s in shares)
                    for i in range(min(len(s[1]) for s in shares))]
    return {
        "algorithm": algorithm, "structure": structure,
        "config": runs[0]["config"], "runs": len(runs),
        "wall_s": med(lambda r: r["process"]["wall_s"]),
        "wall_range": (min(r["process"]["wall_s"] for r in runs),
                       max(r["process"]["wall_s"] for r in runs)),
        "rss_mib": med(lambda r: r["process"]["peak_rss_mib"]),
        **{k: med(lambda r, k=k: r["times_s"][k]) for k in PHASES},
        "wait_s": med(lambda r: r["engine"]["wait_s"]),
        "wait_share": statistics.median(s[0] for s in shares),
        "wait_share_consumers": per_consumer,
        "tets": runs[0]["mesh"]["tetrahedra"],
    }


def main():
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        epilog="examples:\n" + __doc__.split("\n\n")[2],
        formatter_class=argparse.RawDescriptionHelpFormatter)
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--mesh", help="mesh file (with --from-results: only its name is used)")
    where.add_argument("--sample", help="built-in sample, e.g. jittered:256")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--structures", nargs="+", default=STRUCTURES)
    parser.add_argument("--algorithms", nargs="+", default=ALGORITHMS)
    parser.add_argument("--build", default=os.environ.get("ACTOPO_BUILD", ROOT / "build"))
    parser.add_argument("--results", type=Path, default=ROOT / "bench/results",
                        help="where the raw JSON goes, or is read from (default bench/results)")
    parser.add_argument("--from-results", action="store_true",
                        help="plot and tabulate the JSON of an earlier run instead of running")
    parser.add_argument("--plot", help="write a PNG figure here (needs matplotlib)")
    parser.add_argument("--dpi", type=int, default=100, help="of the PNG (default 100)")
    parser.add_argument("extra", nargs="*", help="more actopo-bench flags, after --")
    args = parser.parse_args()
    if args.plot:
        require_matplotlib()
    bench = Path(args.build) / "server/cmd/actopo-bench"
    if not args.from_results and not bench.is_file():
        sys.exit(f"whole_process.py: {bench} not found; build first or pass --build DIR")
    source = ["--mesh", args.mesh] if args.mesh else ["--sample", args.sample]
    name = Path(args.mesh).name if args.mesh else args.sample
    if not args.from_results:
        args.results.mkdir(parents=True, exist_ok=True)
    rows, missing = [], []
    for algorithm in args.algorithms:
        for structure in args.structures:
            tag = f"{Path(name).stem.replace(':', '')}_{structure}_{algorithm}"
            path = args.results / f"whole_{tag}.json"
            if args.from_results:
                if not path.is_file():
                    missing.append(f"{structure} {algorithm}")
                    continue
                runs = json.loads(path.read_text())
            else:
                runs = [run_once(bench, source, structure, algorithm, args.extra)
                        for _ in range(args.runs)]
                path.write_text(json.dumps(runs, indent=1))
            rows.append(summarize(runs, algorithm, structure))
    if missing and rows:
        print(f"whole_process.py: no JSON in {args.results} for {', '.join(missing)}; "
              "left out", file=sys.stderr)
    if not rows:
        sys.exit(f"whole_process.py: no whole_{Path(name).stem.replace(':', '')}_*.json in "
                 f"{args.results} for these structures and algorithms")
    counts = sorted({r["runs"] for r in rows})
    print(f"{name}: {rows[0]['tets']:,} tetrahedra, median of {'/'.join(map(str, counts))} runs, "
          f"whole process (wall s, peak RSS MiB by /usr/bin/time)")
    print()
    print("| algorithm | structure | C / P | wall s (min-max) | peak RSS MiB | load | partition "
          "| preprocess | run | results | wait s |")
    print("|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        c = r["config"]
        threads = f"{c['consumers']} / {c['producers']}" if c["producers"] else f"{c['consumers']}"
        lo, hi = r["wall_range"]
        phases = " | ".join(f"{r[k]:.2f}" for k in [*PHASES, "wait_s"])
        print(f"| {r['algorithm']} | {r['structure']} | {threads} | {r['wall_s']:.2f} "
              f"({lo:.2f}-{hi:.2f}) | {r['rss_mib']:.0f} | {phases} |")
    print()
    print("wait share of the run phase (wait s / (consumers x run s)):",
          ", ".join(f"{r['algorithm']} {r['structure']} {100 * r['wait_share']:.0f}%"
                    for r in rows if r["structure"] != "explicit"))
    if args.plot:
        plot(rows, args.plot, name, args.dpi)


def plot(rows, path, title, dpi):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    algorithms = list(dict.fromkeys(r["algorithm"] for r in rows))
    structures = list(dict.fromkeys(r["structure"] for r in rows))
    fig, (ax_t, ax_m, ax_w) = plt.subplots(1, 3, figsize=(16, 4.6),
                                           gridspec_kw={"width_ratios": [5, 4, 4]})
    width = 0.8 / len(structures)
    colors = ["#888888", "#c9a227", "#6a9fb5", "#2c7bb6", "#d7191c"]
    for s_index, structure in enumerate(structures):
        for a_index, algorithm in enumerate(algorithms):
            r = find(rows, algorithm, structure)
            if r is None:
                continue
            x = a_index + (s_index - (len(structures) - 1) / 2) * width
            bottom = 0.0
            for phase, color in zip(PHASES, colors, strict=True):
                ax_t.bar(x, r[phase], width * 0.9, bottom=bottom, color=color,
                         label=phase if s_index == 0 and a_index == 0 else None)
                bottom += r[phase]
            ax_t.text(x, bottom, structure[0].upper(), ha="center", va="bottom", fontsize=7)
            ax_m.bar(x, r["rss_mib"], width * 0.9, color=f"C{s_index}",
                     label=structure if a_index == 0 else None)
    ax_t.set_ylim(0, 1.08 * max(sum(r[p] for p in PHASES) for r in rows))  # room for the labels
    plot_wait_share(ax_w, rows, algorithms)
    for ax, label in [(ax_t, "seconds (phases, whole process)"), (ax_m, "peak RSS, MiB")]:
        ax.set_xticks(range(len(algorithms)), algorithms, rotation=15)
        ax.set_ylabel(label)
        ax.legend(fontsize=8)
    ax_t.set_title(f"time per phase on {title} (E explicit, C compact, A actopo)", fontsize=9)
    ax_m.set_title(f"peak memory on {title}", fontsize=9)
    fig.tight_layout()
    save_png(fig, path, dpi)


def plot_wait_share(ax, rows, algorithms):
    """actopo's consumers' wait as a share of the run phase per algorithm (dots: each consumer),
    and compact's beside it, hatched: there the 'wait' is the consumer computing its misses."""
    shown = [s for s in ["actopo", "compact"] if any(r["structure"] == s for r in rows)]
    width = 0.8 / max(len(shown), 1)
    for s_index, structure in enumerate(shown):
        actopo = structure == "actopo"
        for a_index, algorithm in enumerate(algorithms):
            r = find(rows, algorithm, structure)
            if r is None:
                continue
            x = a_index + (s_index - (len(shown) - 1) / 2) * width
            share = 100 * r["wait_share"]
            ax.bar(x, share, width * 0.9, color=f"C{STRUCTURES.index(structure)}",
                   alpha=1.0 if actopo else 0.45, hatch=None if actopo else "//",
                   label=(structure if actopo else "compact (computing its own misses)")
                   if a_index == 0 else None)
            ax.text(x, share + 1, f"{share:.0f}%", ha="center", va="bottom", fontsize=7)
            consumers = [100 * s for s in r["wait_share_consumers"]]
            ax.plot([x] * len(consumers), consumers, "k_", markersize=10,
                    label="each actopo consumer" if consumers and a_index == 0 else None)
    ax.set_ylim(0, 105)
    ax.set_xticks(range(len(algorithms)), algorithms, rotation=15)
    ax.set_ylabel("% of the consumers' run-phase time")
    ax.set_title("consumers' wait / (consumers x run phase)", fontsize=9)
    handles, labels = ax.get_legend_handles_labels()
    order = sorted(range(len(labels)), key=lambda i: labels[i].startswith("each"))
    ax.legend([handles[i] for i in order], [labels[i] for i in order], fontsize=7,
              loc="upper left")


def find(rows, algorithm, structure):
    return next((r for r in rows if r["algorithm"] == algorithm and r["structure"] == structure),
                None)


if __name__ == "__main__":
    main()
