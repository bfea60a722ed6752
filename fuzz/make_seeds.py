"""Writes the seed corpora of the fuzz targets (fuzz/corpus/<target>/): small valid inputs for
each, so libFuzzer starts from the shapes a real client or file has. Run from the repository
with the project's virtual environment: .venv/bin/python fuzz/make_seeds.py DATA_DIR
"""

from __future__ import annotations

import hashlib
import struct
import sys
from pathlib import Path

import numpy as np

from actopo._proto import pb

HERE = Path(__file__).resolve().parent / "corpus"


def write(target: str, name: str, data: bytes) -> None:
    (HERE / target).mkdir(parents=True, exist_ok=True)
    (HERE / target / name).write_bytes(data)


def upload(name: str, points: np.ndarray, tets: np.ndarray, fields: dict[str, np.ndarray],
           float32: bool = False, int64: bool = False) -> None:
    p = points.astype(np.float32 if float32 else np.float64)
    t = tets.astype(np.int64 if int64 else np.int32)
    body = p.tobytes() + t.tobytes() + b"".join(v.astype(np.float64).tobytes()
                                                  for v in fields.values())
    header = pb.UploadMeshHeader(
        name=name, num_vertices=len(points), num_tetrahedra=len(tets),
        points_dtype=pb.DATA_TYPE_FLOAT32 if float32 else pb.DATA_TYPE_FLOAT64,
        tetrahedra_dtype=pb.DATA_TYPE_INT64 if int64 else pb.DATA_TYPE_INT32,
        fields=[pb.UploadField(name=k, dtype=pb.DATA_TYPE_FLOAT64) for k in fields],
        sha256=hashlib.sha256(body).hexdigest()).SerializeToString()
    write("upload", name, struct.pack("<H", len(header)) + b"\x06" + header + body)


def lattice(n: int) -> tuple[np.ndarray, np.ndarray]:
    ijk = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    base = np.stack(np.meshgrid(*[np.arange(n - 1)] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    index = lambda c: (c[:, 0] * n + c[:, 1]) * n + c[:, 2]  # noqa: E731
    axes = np.eye(3, dtype=int)
    tets = [np.stack([index(base), index(base + axes[a]), index(base + axes[a] + axes[b]),
                      index(base + 1)], axis=1)
            for a, b in [(0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1)]]
    return ijk.astype(float), np.concatenate(tets)


def main() -> None:
    data = Path(sys.argv[1])
    one = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    upload("one_tet", one, np.array([[0, 1, 2, 3]]), {"s": np.arange(4.0)})
    points, tets = lattice(3)
    upload("lattice3", points, tets, {"h": points[:, 2]}, float32=True, int64=True)

    write("partition", "lattice", b"\x04" + lattice(4)[0].tobytes())
    write("partition", "coincident", b"\x01" + np.zeros(30).tobytes())
    write("partition", "labels", b"\x02" + np.array([3.0, 3, 7, 1, 1, 9]).tobytes())

    for name in ["manifoldCheck0_tet.vtu", "manifoldCheck1_tet.vtu"]:
        write("mesh_file", name, b"\x00" + (data / name).read_bytes())
    write("mesh_file", "legacy.vtk", b"\x01" + b"""# vtk DataFile Version 3.0
two
ASCII
DATASET UNSTRUCTURED_GRID
POINTS 5 double
0 0 0 1 0 0 0 1 0 0 0 1 1 1 1
CELLS 2 10
4 0 1 2 3
4 4 3 2 1
CELL_TYPES 2
10
10
POINT_DATA 5
SCALARS s double 1
LOOKUP_TABLE default
0 1 2 3 4
""")
    write("mesh_file", "image.vti", b"\x02" + b"""<?xml version="1.0"?>
<VTKFile type="ImageData" version="0.1" byte_order="LittleEndian">
<ImageData WholeExtent="0 2 0 2 0 1" Origin="0 0 0" Spacing="1 1 1">
<Piece Extent="0 2 0 2 0 1"><PointData Scalars="s">
<DataArray type="Float64" Name="s" format="ascii">0 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17
</DataArray></PointData></Piece></ImageData></VTKFile>
""")

    ids = pb.Array(dtype=pb.DATA_TYPE_INT64, shape=[3],
                   data=np.array([0, 5, 124], dtype=np.int64).tobytes())
    requests = {
        "relation": (0, pb.GetRelationRequest(relation=pb.RELATION_VERTEX_STAR,
                                              simplex=pb.Simplex(id=7))),
        "relation_tuple": (0, pb.GetRelationRequest(
            relation=pb.RELATION_EDGE_TRIANGLES,
            simplex=pb.Simplex(vertices=pb.VertexTuple(ids=[0, 1])))),
        "batch": (1, pb.GetRelationBatchRequest(relation=pb.RELATION_VERTEX_EDGES, ids=ids)),
        "open": (2, pb.OpenSessionRequest(structure=pb.STRUCTURE_ACTOPO,
                                          engine=pb.EngineOptions(consumers=1, producers=1))),
        "load": (3, pb.LoadMeshRequest(sample="jittered:4")),
        "job": (4, pb.RunJobRequest(algorithm=pb.ALGORITHM_CRITICAL_POINTS)),
        "stream": (5, pb.StreamRelationsRequest(relation=pb.RELATION_VERTEX_STAR, ids=ids)),
        "job_over_fields": (4, pb.RunJobRequest(algorithm=pb.ALGORITHM_DIAGRAM_DISTANCE,
                                                all_fields=True)),
        "add_fields": (6, pb.AddFieldsHeader(
            fields=[pb.UploadField(name="f", dtype=pb.DATA_TYPE_FLOAT64, time=2.0)])),
        "delete_field": (7, pb.DeleteFieldRequest(name="f")),
        "stats": (8, pb.GetSessionStatsRequest()),
        "download": (9, pb.DownloadMeshRequest(fields=["scalar"])),
        "load_files": (3, pb.LoadMeshRequest(files=pb.FileSeries(paths=["a.vtu", "b.vtu"],
                                                                 times=[0.5, 1.5]))),
        "create_upload": (10, pb.CreateUploadRequest(files=[
            pb.UploadFileInfo(path="run.pvd", size=120, sha256="0" * 64),
            pb.UploadFileInfo(path="steps/a.vtu", size=4096, sha256="a" * 64)])),
        "get_upload": (12, pb.GetUploadRequest()),
        "load_upload": (3, pb.LoadMeshRequest(upload="upload-0")),
    }
    # WriteUpload: the start's length, the start (file 0 from offset 0), then chunks' bytes.
    start = pb.WriteUploadStart(file=0, offset=0).SerializeToString()
    write("request", "write_upload", bytes([11, len(start)]) + start + bytes(range(64)))
    for name, (kind, message) in requests.items():
        write("request", name, bytes([kind]) + message.SerializeToString())


if __name__ == "__main__":
    main()
