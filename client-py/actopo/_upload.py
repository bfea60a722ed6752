"""The UploadMesh message stream: a header, then ~1 MiB chunks of the concatenated arrays."""

from __future__ import annotations

import hashlib
import itertools
from collections.abc import Iterator

from actopo._arrays import code_of
from actopo._mesh import MeshArrays
from actopo._proto import pb

CHUNK_BYTES = 1 << 20


def _buffers(mesh: MeshArrays) -> list[memoryview]:
    arrays = [mesh.points, mesh.tetrahedra, *mesh.point_data.values()]
    return [a.data.cast("B") for a in arrays]


def header(mesh: MeshArrays, partition: pb.PartitionOptions) -> pb.UploadMeshHeader:
    """The first message: sizes, dtypes, fields in order and the SHA-256 of all bytes."""
    digest = hashlib.sha256()
    for buffer in _buffers(mesh):
        digest.update(buffer)
    return pb.UploadMeshHeader(
        name=mesh.name, num_vertices=len(mesh.points), num_tetrahedra=len(mesh.tetrahedra),
        points_dtype=code_of(mesh.points.dtype), tetrahedra_dtype=code_of(mesh.tetrahedra.dtype),
        fields=[pb.UploadField(name=k, dtype=code_of(v.dtype))
                for k, v in mesh.point_data.items()],
        sha256=digest.hexdigest(), partition=partition)


def requests(mesh: MeshArrays, partition: pb.PartitionOptions,
             chunk_bytes: int = CHUNK_BYTES) -> Iterator[pb.UploadMeshRequest]:
    """The whole upload. The header is made before this returns, so a problem surfaces here
    rather than inside gRPC's request thread. Chunks have exactly `chunk_bytes` bytes (the last
    may be shorter) and may straddle two arrays: the payload is one byte stream."""
    first = pb.UploadMeshRequest(header=header(mesh, partition))
    return itertools.chain([first], _chunks(mesh, chunk_bytes))


def _chunks(mesh: MeshArrays, chunk_bytes: int) -> Iterator[pb.UploadMeshRequest]:
    pending: list[memoryview] = []
    size = 0
    for buffer in _buffers(mesh):
        while len(buffer):
            take = buffer[:chunk_bytes - size]
            pending.append(take)
            size += len(take)
            buffer = buffer[len(take):]
            if size == chunk_bytes:
                yield pb.UploadMeshRequest(chunk=b"".join(pending))
                pending, size = [], 0
    if size:
        yield pb.UploadMeshRequest(chunk=b"".join(pending))
