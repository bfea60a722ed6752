"""The client's memory when it uploads a very large mesh file (issue 52's 100M-tetrahedron target).

    .venv/bin/python bench/upload_large_file.py --target HOST:PORT [--n 272] [--file F.vtu]

Writes (unless --file exists) an n^3-point grid split into 6 tetrahedra per cube as a raw
appended .vtu, slab by slab, so that writing it needs no more memory than one slab (n = 272:
20.1M points, 119.4M tetrahedra, 2.83 GB). Then, in this process, sends it the way
Client.upload_file does before its load (CreateUpload, WriteUpload), asks the server what it
holds, deletes the upload, and prints the seconds and this process's peak resident memory. The
load itself is left out: it measures the server, not the client. Start the server with an
--upload-budget-mib above the file's size.
"""

from __future__ import annotations

import argparse
import resource
import time
from pathlib import Path

import numpy as np

import actopo
from actopo import _file_upload
from actopo._client import UPLOAD_PHASES, make_load_progress
from actopo._proto import pb

KUHN = [(0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)]
"""The 6 tetrahedra of a cube: from corner (0,0,0) to (1,1,1), one axis at a time."""


def write_grid(n: int, out: Path) -> int:
    """Writes the grid; returns its tetrahedron count."""
    points, cells = n**3, (n - 1) ** 3 * 6
    sizes = {"f": points * 4, "p": points * 12, "c": cells * 16, "o": cells * 4, "t": cells}
    offsets, at = {}, 0
    for key, size in sizes.items():
        offsets[key] = at
        at += 8 + size  # each array is preceded by its byte count (header_type UInt64)

    def array(kind: str, key: str, name: str = "", components: int = 1) -> str:
        named = f' Name="{name}"' if name else ""
        wide = f' NumberOfComponents="{components}"' if components > 1 else ""
        return (f'<DataArray type="{kind}"{named}{wide} format="appended" '
                f'offset="{offsets[key]}"/>')

    header = (
        '<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" '
        'byte_order="LittleEndian" header_type="UInt64">\n<UnstructuredGrid>\n'
        f'<Piece NumberOfPoints="{points}" NumberOfCells="{cells}">\n'
        f'<PointData Scalars="f">{array("Float32", "f", "f")}</PointData>\n'
        f'<Points>{array("Float32", "p", components=3)}</Points>\n'
        f'<Cells>{array("Int32", "c", "connectivity")}{array("Int32", "o", "offsets")}'
        f'{array("UInt8", "t", "types")}</Cells>\n</Piece>\n</UnstructuredGrid>\n'
        '<AppendedData encoding="raw">\n_')
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="xy")
    ci, cj = (a.ravel() for a in np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="xy"))
    per_slab = (n - 1) ** 2 * 6
    with out.open("wb") as f:
        f.write(header.encode())
        f.write(np.uint64(sizes["f"]).tobytes())
        for k in range(n):
            x, y, z = i / n - 0.5, j / n - 0.5, k / n - 0.5
            f.write((np.sin(7 * x) * np.cos(5 * y) + z * z).astype(np.float32).tobytes())
        f.write(np.uint64(sizes["p"]).tobytes())
        for k in range(n):
            f.write(np.stack([i, j, np.full_like(i, k)], axis=-1).astype(np.float32).tobytes())
        f.write(np.uint64(sizes["c"]).tobytes())
        for k in range(n - 1):
            tets = []
            for order in KUHN:
                step = [0, 0, 0]
                corners = [(k * n + cj) * n + ci]
                for axis in order:
                    step[axis] += 1
                    corners.append(((k + step[2]) * n + cj + step[1]) * n + ci + step[0])
                tets.append(np.stack(corners, axis=-1))
            f.write(np.stack(tets, axis=1).astype(np.int32).tobytes())
        f.write(np.uint64(sizes["o"]).tobytes())
        for k in range(n - 1):
            ends = (np.arange(1, per_slab + 1, dtype=np.int64) + k * per_slab) * 4
            f.write(ends.astype(np.int32).tobytes())
        f.write(np.uint64(sizes["t"]).tobytes())
        for _ in range(n - 1):
            f.write(np.full(per_slab, 10, dtype=np.uint8).tobytes())  # VTK_TETRA
        f.write(b"\n</AppendedData>\n</VTKFile>\n")
    return cells


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--target", required=True, help="the server, HOST:PORT")
    p.add_argument("--n", type=int, default=272, help="points per side (default 272)")
    p.add_argument("--file", type=Path, default=Path("/tmp/actopo-bench-upload/grid.vtu"))
    args = p.parse_args()
    if not args.file.exists():
        args.file.parent.mkdir(parents=True, exist_ok=True)
        print(f"writing {args.file}: {write_grid(args.n, args.file):,} tetrahedra")
    with actopo.Client(args.target) as client:
        start = time.monotonic()
        files = _file_upload.upload_plan(args.file)
        hashed = time.monotonic()
        bar = make_load_progress(None, _file_upload.description(files), UPLOAD_PHASES)
        upload_id = client._send_files(files, bar)
        sent = time.monotonic()
        held = client._stub.GetUpload(pb.GetUploadRequest(upload_id=upload_id)).upload
        client._delete_upload(upload_id)
    peak_mib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"{files[0].size / 1e9:.2f} GB: hashed in {hashed - start:.1f} s, sent in "
          f"{sent - hashed:.1f} s; the server held {sum(held.received_bytes):,} bytes, complete "
          f"{held.complete}; client peak resident {peak_mib:.0f} MiB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
