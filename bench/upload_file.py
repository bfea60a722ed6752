#!/usr/bin/env python3
"""A mesh file uploaded as its bytes against the server's own load of it (issue 52): whole
process, start to exit, medians of --runs, alternated in one run.

    .venv/bin/python bench/upload_file.py                   # ../shared/data/wavelet128.vtu
    .venv/bin/python bench/upload_file.py --mesh F.vtu --runs 3 --json

Each run is a fresh Python process (`python -c`, the client imported, connected, the call, the
mesh deleted, exit) of:

- upload:  Client.upload_file(FILE): the SHA-256, CreateUpload, the bytes in 1 MiB chunks,
           LoadMesh of the upload (the server reads it as a data-directory file);
- load:    Client.load_mesh(NAME): the server's own load of the same file from its data
           directory (the server runs with --data-dir the file's folder);
- decoded: Client.upload_mesh(arrays read with pyvista): the decoded upload (UploadMesh), as
           `--upload FILE` sent a file before (--no-decoded leaves it out).

Figures: wall_s (the process, as a user waits for it), call_s (the call alone, in the process),
the client's peak resident size (ru_maxrss at exit) and how much of it the call added over the
process connected and idle. Bytes on the wire: one more run of each upload through a counting
TCP proxy (client-py/tests/proxy.py): every byte the client sent, HTTP/2 and gRPC framing and
the other calls included. Resumption: an upload through the proxy cut at half the file
(a reset connection), its bytes sent in all.

Without --mesh, ../shared/data/wavelet128.vtu is used, and written first with
../shared/data/make_wavelet_vtu.py 128 into --scratch when it is not there (about 30 s, 2 GiB):
the reference file of the issue's figures (73 MB, 10,241,915 tetrahedra).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
sys.path.insert(0, str(ROOT / "client-py"))
sys.path.insert(0, str(ROOT / "client-py" / "tests"))

from proxy import cutting_proxy  # noqa: E402  (client-py/tests: the counting, cutting proxy)

# One run: what a user's program does, timed and measured from inside as well.
CLIENT = """
import json, resource, sys, time
import actopo
from actopo._mesh import mesh_arrays
target, how, path = sys.argv[1:4]
with actopo.Client(target) as client:
    client.server_info()
    idle = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    start = time.perf_counter()
    if how == "upload":
        mesh = client.upload_file(path)
    elif how == "load":
        mesh = client.load_mesh(path)
    else:
        mesh = client.upload_mesh(mesh_arrays(path))
    call_s = time.perf_counter() - start
    client.delete_mesh(mesh)
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps({"call_s": call_s, "idle_kib": idle, "peak_kib": peak,
                  "tetrahedra": mesh.tetrahedra, "source": mesh.source}))
"""
MB = 1e6


def start_server(binary: Path, data_dir: Path) -> tuple[subprocess.Popen[str], str]:
    server = subprocess.Popen([str(binary), "--host", "127.0.0.1", "--port", "0", "--data-dir",
                               str(data_dir)], stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True)
    assert server.stdout is not None
    for line in server.stdout:
        if match := re.search(r"listening on (\S+)", line):
            return server, match.group(1)
    raise SystemExit(f"{binary} exited before listening")


def client_run(target: str, how: str, path: str) -> dict[str, Any]:
    """One whole-process run of `how`; its figures."""
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", CLIENT, target, how, path],
                          capture_output=True, text=True, timeout=1800)
    wall = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"{how}: {done.stderr}")
    figures = json.loads(done.stdout)
    return {"wall_s": wall, "call_s": figures["call_s"],
            "client_peak_mb": figures["peak_kib"] * 1024 / MB,
            "client_added_mb": (figures["peak_kib"] - figures["idle_kib"]) * 1024 / MB,
            "tetrahedra": figures["tetrahedra"], "source": figures["source"]}


def wire_bytes(target: str, how: str, path: str, cut_after: int | None = None) -> dict[str, Any]:
    """The bytes the client sent through a counting proxy in one run (cut once after
    `cut_after` bytes)."""
    with cutting_proxy(target, cut_after=cut_after) as proxy:
        figures = client_run(proxy.target, how, path)
        return {"sent_bytes": proxy.sent, "cuts": proxy.cuts, "wall_s": figures["wall_s"]}


def default_mesh(scratch: Path) -> Path:
    """../shared/data/wavelet128.vtu, else the same file written into `scratch`."""
    for folder in (DATA, scratch):
        if (folder / "wavelet128.vtu").is_file():
            return folder / "wavelet128.vtu"
    scratch.mkdir(parents=True, exist_ok=True)
    print(f"writing {scratch / 'wavelet128.vtu'} (make_wavelet_vtu.py 128, about 30 s)",
          file=sys.stderr)
    subprocess.run([sys.executable, str(DATA / "make_wavelet_vtu.py"), "128",
                    str(scratch / "wavelet128.vtu")], check=True, stdout=sys.stderr)
    return scratch / "wavelet128.vtu"


def median(runs: list[dict[str, Any]], key: str) -> float:
    return float(statistics.median(r[key] for r in runs))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mesh", type=Path, help="a .vtu, .vtk, .vti or .pvd (default: "
                        "wavelet128.vtu)")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--no-decoded", action="store_true",
                        help="leave out the decoded upload (UploadMesh of pyvista's arrays)")
    parser.add_argument("--server-bin", type=Path,
                        default=ROOT / "build/server/cmd/actopo-server")
    parser.add_argument("--scratch", type=Path, default=Path("/tmp/actopo-bench-upload"),
                        help="where wavelet128.vtu is written when it is missing")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    mesh = (args.mesh or default_mesh(args.scratch)).resolve()
    size = mesh.stat().st_size
    kinds = ["upload", "load"] + ([] if args.no_decoded else ["decoded"])
    server, target = start_server(args.server_bin, mesh.parent)
    try:
        paths = {"upload": str(mesh), "load": mesh.name, "decoded": str(mesh)}
        client_run(target, "load", mesh.name)  # the page cache and the server warmed up
        runs: dict[str, list[dict[str, Any]]] = {k: [] for k in kinds}
        for k in range(args.runs):
            for kind in kinds:
                runs[kind].append(client_run(target, kind, paths[kind]))
                print(f"run {k + 1}/{args.runs} {kind}: {runs[kind][-1]['wall_s']:.2f} s",
                      file=sys.stderr)
        wire = {kind: wire_bytes(target, kind, paths[kind]) for kind in kinds if kind != "load"}
        cut = wire_bytes(target, "upload", str(mesh), cut_after=size // 2)
    finally:
        server.terminate()
        server.wait()
    rows = {kind: {"wall_s": median(runs[kind], "wall_s"),
                   "call_s": median(runs[kind], "call_s"),
                   "client_peak_mb": median(runs[kind], "client_peak_mb"),
                   "client_added_mb": median(runs[kind], "client_added_mb"),
                   "wire_bytes": wire.get(kind, {}).get("sent_bytes"),
                   "runs": runs[kind]} for kind in kinds}
    upload, load = rows["upload"], rows["load"]
    report = {
        "mesh": str(mesh), "file_bytes": size, "tetrahedra": runs["upload"][0]["tetrahedra"],
        "runs": args.runs, "rows": rows,
        "resumed": {"cut_after_bytes": size // 2, "sent_bytes": cut["sent_bytes"],
                    "cuts": cut["cuts"], "sent_over_file": cut["sent_bytes"] / size},
        "targets": {
            "upload_over_load": upload["wall_s"] / load["wall_s"],
            "client_peak_mb": upload["client_peak_mb"],
            "wire_over_file": upload["wire_bytes"] / size,
            "resumed_over_file": cut["sent_bytes"] / size,
        },
    }
    if args.json:
        print(json.dumps(report, indent=1))
        return
    print(f"{mesh.name}: {size / MB:.1f} MB, {report['tetrahedra']:,} tetrahedra; whole "
          f"process, medians of {args.runs}")
    print(f"{'':<9} {'wall_s':>7} {'call_s':>7} {'client_peak_MB':>15} {'call_added_MB':>14} "
          f"{'wire_MB':>8} {'wire/file':>9}")
    for kind, row in rows.items():
        wire_mb = "-" if row["wire_bytes"] is None else f"{row['wire_bytes'] / MB:.1f}"
        ratio = "-" if row["wire_bytes"] is None else f"{row['wire_bytes'] / size:.3f}"
        print(f"{kind:<9} {row['wall_s']:>7.2f} {row['call_s']:>7.2f} "
              f"{row['client_peak_mb']:>15.0f} {row['client_added_mb']:>14.0f} {wire_mb:>8} "
              f"{ratio:>9}")
    targets = report["targets"]
    print(f"cut at half ({cut['cuts']} cut), resumed: {cut['sent_bytes'] / MB:.1f} MB sent in "
          f"all, {targets['resumed_over_file']:.3f} x the file")
    print(f"targets: upload/load {targets['upload_over_load']:.2f} (<= 1.3), client peak "
          f"{targets['client_peak_mb']:.0f} MB (<= 100), wire {targets['wire_over_file']:.3f} "
          f"x the file (<= 1.05), resumed {targets['resumed_over_file']:.3f} x (<= 1.1)")


if __name__ == "__main__":
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    main()
