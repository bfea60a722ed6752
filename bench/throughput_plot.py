#!/usr/bin/env python3
"""Relation throughput and latency against concurrent clients, one line per structure.

Starts actopo-server on a free loopback port (or uses --target), runs the Python load tool
(`actopo bench`) over every structure, mode and client count --repeat times (each sweep starts
from another structure, so a slow spell of a shared machine does not fall on one), saves the
JSON reports to bench/results/ and, with --plot, draws a figure: per mode, simplices per second
against clients (one line per structure: the median, shaded between the lowest and highest
sweep) and the median p50 and p99 latency of a call. Each point runs --duration seconds on one
session per structure shared by all its clients. The default (3 structures, batch and unary,
1-16 clients, 2 s a point, 3 sweeps) takes about 3.5 minutes on wavelet:80, its load and
sessions included. Needs the Python client (`make deps` puts it and matplotlib in .venv).

    .venv/bin/python bench/throughput_plot.py --plot bench/throughput_wavelet80.png
    .venv/bin/python bench/throughput_plot.py --mesh fertility_tet.vtu --modes batch \\
        --clients 1,4,16 --duration 1 --plot /tmp/fertility.png
    .venv/bin/python bench/throughput_plot.py --target 127.0.0.1:50051 --sample wavelet:40
    .venv/bin/python bench/throughput_plot.py \\
        --from-results bench/results/throughput_wavelet80.json --plot bench/throughput_wavelet80.png

More `actopo bench` flags go after --, e.g. `-- --batch-size 65536 --query-readers 4`.
"""
import argparse
import contextlib
import datetime
import importlib.util
import json
import os
import select
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _plotting import require_matplotlib, save_png

ROOT = Path(__file__).resolve().parents[1]
STRUCTURES = ["explicit", "compact", "actopo"]  # colours C0, C1, C2 as in whole_process.py
MODES = ["unary", "batch", "stream"]
STARTUP_SECONDS = 30


def comma_list(choices=None, convert=str):
    """An argparse type: comma-separated values, converted and checked against `choices`."""
    def parse(text):
        values = [convert(v.strip()) for v in text.split(",") if v.strip()]
        bad = [v for v in values if choices is not None and v not in choices]
        if not values or bad:
            raise argparse.ArgumentTypeError(
                f"'{text}': give a comma-separated list of {', '.join(choices or ['numbers'])}")
        return values
    return parse


def default_data_dir():
    for candidate in [os.environ.get("ACTOPO_DATA_DIR"), ROOT.parent / "shared/data",
                      "/work/shared/data"]:
        if candidate and Path(candidate).is_dir():
            return Path(candidate)
    return None


class Server:
    """actopo-server on 127.0.0.1, a free port; stopped with SIGTERM at the end of a with."""

    def __init__(self, binary, data_dir):
        if not binary.is_file():
            sys.exit(f"throughput_plot.py: {binary} not found; build first, pass --build DIR "
                     "or use --target HOST:PORT")
        command = [str(binary), "--host", "127.0.0.1", "--port", "0"]
        if data_dir is not None:
            command += ["--data-dir", str(data_dir)]
        # A file, not a pipe: a pipe nobody reads could stall the server. Closed in stop().
        self._log = tempfile.TemporaryFile("w+")  # noqa: SIM115
        self.process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=self._log,
                                        text=True)
        self.target = self._wait_for_port()

    def _wait_for_port(self):
        deadline = time.monotonic() + STARTUP_SECONDS
        while time.monotonic() < deadline:
            ready, _, _ = select.select([self.process.stdout], [], [], 0.5)
            line = self.process.stdout.readline() if ready else ""
            if line.startswith("actopo-server listening on "):
                return line.split(" on ", 1)[1].strip()
            if self.process.poll() is not None:
                break
        log = self.log()
        self.stop()
        sys.exit(f"throughput_plot.py: actopo-server did not start: {log}")

    def log(self):
        self._log.seek(0)
        return self._log.read().strip() or "(nothing on stderr)"

    def stop(self):
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=15)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self._log.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()


def run_bench(args, target, structures):
    """One `actopo bench --json` over the whole sweep; returns its report."""
    source = ["--mesh", args.mesh] if args.mesh else ["--sample", args.sample]
    command = [sys.executable, "-m", "actopo", "--server", target, "bench", "--json", *source,
               "--structure", ",".join(structures), "--modes", ",".join(args.modes),
               "--clients", ",".join(map(str, args.clients)), "--duration", str(args.duration),
               "--relation", args.relation, *args.extra]
    points = len(structures) * len(args.modes) * len(args.clients)
    print(f"throughput_plot.py: {points} points of {args.duration:g} s on {target}: "
          f"{' '.join(command[2:])}", file=sys.stderr, flush=True)
    started = time.monotonic()
    proc = subprocess.run(command, stdout=subprocess.PIPE, text=True)
    if proc.returncode != 0:
        sys.exit(f"throughput_plot.py: actopo bench failed (exit {proc.returncode})")
    report = json.loads(proc.stdout)
    report["sweep"] = {
        "command": ["actopo", *command[3:]], "seconds": time.monotonic() - started,
        "date": datetime.datetime.now().isoformat(timespec="seconds"),
        "cores": os.cpu_count(), "server": "started by throughput_plot.py"
        if args.target is None else args.target}
    return report


def summarize(reports):
    """One point per structure, mode and client count over the sweeps: throughput median and
    range, median p50 and p99 latency, errors summed; in the order of the first sweep's modes
    and client counts, structures as in STRUCTURES."""
    groups = {}
    for report in reports:
        for r in report["runs"]:
            if r["mode"] != "job":
                groups.setdefault((r["structure"], r["mode"], r["clients"]), []).append(r)
    def order(key):
        structure, mode, clients = key
        return (STRUCTURES.index(structure) if structure in STRUCTURES else len(STRUCTURES),
                structure, mode, clients)
    points = []
    for key in sorted(groups, key=order):
        runs = groups[key]
        rates = [r["simplices_per_s"] for r in runs]
        points.append({
            "structure": key[0], "mode": key[1], "clients": key[2], "sweeps": len(runs),
            "rate": statistics.median(rates), "rate_low": min(rates), "rate_high": max(rates),
            **{k: statistics.median(r["latency_ms"][k] for r in runs) for k in ("p50", "p99")},
            "errors": sum(r["errors"] for r in runs)})
    return points


def print_table(reports, points):
    first = reports[0]
    print(f"{first['config']['relation']} on {first['mesh']['name']} "
          f"({first['mesh']['tetrahedra']:,} tetrahedra, {first['mesh']['blocks']} blocks), "
          f"{first['config']['duration_s']} s a point, medians of {len(reports)} sweeps")
    print()
    print("| structure | mode | clients | simplices/s (min-max) | p50 ms | p99 ms | errors |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for p in points:
        print(f"| {p['structure']} | {p['mode']} | {p['clients']} | {p['rate']:,.0f} "
              f"({short(p['rate_low'])}-{short(p['rate_high'])}) | {p['p50']:.2f} | "
              f"{p['p99']:.2f} | {p['errors']} |")


def short(value):
    """1500000 -> '1.5M', 2500 -> '2.5k'."""
    for scale, suffix in [(1e6, "M"), (1e3, "k")]:
        if abs(value) >= scale:
            return f"{value / scale:.3g}{suffix}"
    return f"{value:.3g}"


def plot(reports, points, path, dpi):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter
    modes = list(dict.fromkeys(r["mode"] for r in reports[0]["runs"] if r["mode"] != "job"))
    structures = list(dict.fromkeys(p["structure"] for p in points))
    clients = sorted({p["clients"] for p in points})
    fig, axes = plt.subplots(len(modes), 2, figsize=(11, 3.8 * len(modes)), squeeze=False)
    config, mesh = reports[0]["config"], reports[0]["mesh"]
    for (ax_s, ax_l), mode in zip(axes, modes, strict=True):
        for structure in structures:
            line = [p for p in points if p["mode"] == mode and p["structure"] == structure]
            x = [p["clients"] for p in line]
            color = f"C{STRUCTURES.index(structure)}" if structure in STRUCTURES else None
            ax_s.plot(x, [p["rate"] for p in line], "o-", color=color, label=structure)
            if len(reports) > 1:
                ax_s.fill_between(x, [p["rate_low"] for p in line],
                                  [p["rate_high"] for p in line], color=color, alpha=0.15)
            ax_l.plot(x, [p["p50"] for p in line], "o-", color=color, label=structure)
            ax_l.plot(x, [p["p99"] for p in line], "v--", color=color)
        size = {"batch": f", {config['batch_size']} ids a call",
                "stream": f", arrays of {config['stream_size']}"}.get(mode, "")
        ax_s.set_title(f"{mode}{size}: {config['relation']} on {mesh['name']}", fontsize=9)
        ax_l.set_title(f"{mode}: latency of a {'call' if mode != 'stream' else 'streamed array'}"
                       " (p50 solid, p99 dashed)", fontsize=9)
        ax_s.set_ylabel("simplices/s")
        ax_s.set_ylim(bottom=0)
        ax_s.yaxis.set_major_formatter(FuncFormatter(lambda v, _: short(v)))
        ax_l.set_ylabel("ms (log scale)")
        ax_l.set_yscale("log")
        ax_l.yaxis.set_major_locator(LogLocator(base=10, subs=(1, 2, 5)))
        ax_l.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        ax_l.yaxis.set_minor_formatter(NullFormatter())
        for ax in (ax_s, ax_l):
            ax.set_xscale("log", base=2)
            ax.set_xticks(clients, [str(c) for c in clients])
            ax.set_xlabel("concurrent clients")
            ax.grid(alpha=0.3)
        ax_s.legend(fontsize=8)
        ax_l.legend(fontsize=8)
    sweep = reports[0].get("sweep", {})
    fig.suptitle(f"{mesh['tetrahedra']:,} tetrahedra, {mesh['blocks']} blocks; "
                 f"{config['duration_s']} s a point, medians of {len(reports)} sweeps; server "
                 f"and clients on one machine ({sweep.get('cores', '?')} cores)", fontsize=9)
    fig.tight_layout()
    save_png(fig, path, dpi)


def main():
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        epilog="examples:\n" + __doc__.split("\n\n")[2],
        formatter_class=argparse.RawDescriptionHelpFormatter)
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--mesh", help="a file under the server's data directory")
    where.add_argument("--sample", help="a built-in sample (default wavelet:80)")
    where.add_argument("--from-results", type=Path, metavar="JSON",
                       help="plot the reports this script saved instead of running")
    parser.add_argument("--target", metavar="HOST:PORT",
                        help="a running actopo-server (default: start one)")
    parser.add_argument("--build", type=Path,
                        default=os.environ.get("ACTOPO_BUILD", ROOT / "build"),
                        help="where actopo-server is built (default build/)")
    parser.add_argument("--data-dir", type=Path, default=default_data_dir(),
                        help="the started server's --data-dir (default ../shared/data)")
    parser.add_argument("--structures", type=comma_list(STRUCTURES), default=STRUCTURES)
    parser.add_argument("--modes", type=comma_list(MODES), default=["batch", "unary"],
                        help="of unary, batch, stream (default batch,unary)")
    parser.add_argument("--clients", type=comma_list(convert=int), default=[1, 2, 4, 8, 16])
    parser.add_argument("--duration", type=float, default=2.0, help="seconds a point")
    parser.add_argument("--repeat", type=int, default=3, help="sweeps (default 3)")
    parser.add_argument("--relation", default="vertex_star")
    parser.add_argument("--results", type=Path,
                        help="where the JSON reports go (default "
                             "bench/results/throughput_<mesh>.json)")
    parser.add_argument("--plot", help="write a PNG figure here (needs matplotlib)")
    parser.add_argument("--dpi", type=int, default=100, help="of the PNG (default 100)")
    parser.add_argument("extra", nargs="*", help="more `actopo bench` flags, after --")
    args = parser.parse_args()
    if args.plot:
        require_matplotlib()
    if args.repeat < 1:
        parser.error(f"--repeat: {args.repeat} is not positive")
    if args.from_results:
        reports = json.loads(args.from_results.read_text())
        reports = reports if isinstance(reports, list) else [reports]
    else:
        if importlib.util.find_spec("actopo") is None:
            sys.exit(f"throughput_plot.py: the Python client (package actopo) is not installed "
                     f"for {sys.executable}; run with .venv/bin/python (make deps) or "
                     "`pip install ./client-py`")
        if args.mesh is None and args.sample is None:
            args.sample = "wavelet:80"
        started = time.monotonic()
        with contextlib.ExitStack() as stack:
            target = args.target or stack.enter_context(
                Server(args.build / "server/cmd/actopo-server", args.data_dir)).target
            reports = []
            for sweep in range(args.repeat):
                turn = sweep % len(args.structures)
                structures = args.structures[turn:] + args.structures[:turn]
                reports.append(run_bench(args, target, structures))
        name = Path(args.mesh).stem if args.mesh else args.sample.replace(":", "")
        path = args.results or ROOT / f"bench/results/throughput_{name}.json"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(reports, indent=1))
        print(f"throughput_plot.py: {time.monotonic() - started:.0f} s in all; wrote {path}",
              file=sys.stderr)
    points = summarize(reports)
    print_table(reports, points)
    if args.plot:
        plot(reports, points, args.plot, args.dpi)


if __name__ == "__main__":
    main()
