"""The byte streams of UploadMesh and AddFields: a header, then ~1 MiB chunks of the
concatenated arrays, with the SHA-256 of those bytes (in the header of an upload, after the
chunks of AddFields)."""

from __future__ import annotations

import hashlib
import itertools
from collections.abc import Iterable, Iterator, Sequence

from actopo._arrays import code_of
from actopo._fields import FieldArray
from actopo._mesh import MeshArrays
from actopo._proto import pb

CHUNK_BYTES = 1 << 20


def _buffers(mesh: MeshArrays) -> list[memoryview]:
    arrays = [mesh.points, mesh.tetrahedra, *mesh.point_data.values()]
    return [a.data.cast("B") for a in arrays]


def _sha256(buffers: Iterable[memoryview]) -> str:
    """The digest of the buffers' bytes one after the other, fed buffer by buffer (never
    joined)."""
    digest = hashlib.sha256()
    for buffer in buffers:
        digest.update(buffer)
    return digest.hexdigest()


def header(mesh: MeshArrays, partition: pb.PartitionOptions) -> pb.UploadMeshHeader:
    """The first message: sizes, dtypes, fields in order and the SHA-256 of all bytes."""
    return pb.UploadMeshHeader(
        name=mesh.name, num_vertices=len(mesh.points), num_tetrahedra=len(mesh.tetrahedra),
        points_dtype=code_of(mesh.points.dtype), tetrahedra_dtype=code_of(mesh.tetrahedra.dtype),
        fields=[pb.UploadField(name=k, dtype=code_of(v.dtype))
                for k, v in mesh.point_data.items()],
        sha256=_sha256(_buffers(mesh)), partition=partition)


def requests(mesh: MeshArrays, partition: pb.PartitionOptions,
             chunk_bytes: int = CHUNK_BYTES) -> Iterator[pb.UploadMeshRequest]:
    """The whole upload. The header is made before this returns, so a problem surfaces here
    rather than inside gRPC's request thread. Chunks have exactly `chunk_bytes` bytes (the last
    may be shorter) and may straddle two arrays: the payload is one byte stream."""
    first = pb.UploadMeshRequest(header=header(mesh, partition))
    return itertools.chain([first], (pb.UploadMeshRequest(chunk=c)
                                     for c in chunks(_buffers(mesh), chunk_bytes)))


def add_fields_requests(mesh_id: str, fields: Sequence[FieldArray],
                        chunk_bytes: int = CHUNK_BYTES) -> Iterator[pb.AddFieldsRequest]:
    """The messages of AddFields: the header (the fields in order, with their dtypes and
    times), made before this returns, then the values in chunks as for an upload, then the
    SHA-256 of those bytes (header.sha256_last): each chunk is hashed as it goes, while gRPC
    sends the ones before it, so the values are read once. Only one chunk is held at a time
    besides the fields themselves."""
    buffers = [f.values.data.cast("B") for f in fields]
    first = pb.AddFieldsRequest(header=pb.AddFieldsHeader(
        mesh_id=mesh_id, sha256_last=True,
        fields=[pb.UploadField(name=f.name, dtype=code_of(f.values.dtype), time=f.time)
                for f in fields]))

    def rest() -> Iterator[pb.AddFieldsRequest]:
        digest = hashlib.sha256()
        for chunk in chunks(buffers, chunk_bytes):
            digest.update(chunk)
            yield pb.AddFieldsRequest(chunk=chunk)
        yield pb.AddFieldsRequest(sha256=digest.hexdigest())

    return itertools.chain([first], rest())


def chunks(buffers: Iterable[memoryview], chunk_bytes: int) -> Iterator[bytes]:
    """The buffers' bytes one after the other, cut into pieces of exactly `chunk_bytes` (the
    last may be shorter); a piece may straddle two buffers."""
    pending: list[memoryview] = []
    size = 0
    for buffer in buffers:
        while len(buffer):
            take = buffer[:chunk_bytes - size]
            pending.append(take)
            size += len(take)
            buffer = buffer[len(take):]
            if size == chunk_bytes:
                yield b"".join(pending)
                pending, size = [], 0
    if size:
        yield b"".join(pending)
