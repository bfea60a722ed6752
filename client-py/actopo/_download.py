"""DownloadMesh's stream decoded as it arrives: the header's arrays are allocated once, then each
chunk's bytes are copied into them in place, so that the mesh is held once and its bytes are
never joined. A chunk may end inside a value or straddle two arrays: the payload is one byte
stream (points, tetrahedra, then each field), as an upload's is."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from actopo._arrays import dtype_of
from actopo._errors import ActopoError
from actopo._mesh import MeshArrays
from actopo._proto import pb


def _array(shape: tuple[int, ...], code: int, what: str, kinds: str) -> np.ndarray:
    """An array for `what` of the header's dtype, which must be 4 or 8 bytes of `kinds`."""
    dtype = dtype_of(code)
    if dtype.kind not in kinds or dtype.itemsize not in (4, 8):
        raise ActopoError(f"DownloadMesh: {what} of dtype {dtype.name} in the header")
    return np.empty(shape, dtype)


def _bytes(array: np.ndarray) -> memoryview:
    """A writable byte view of the array (zero-sized arrays too, which memoryview.cast
    refuses)."""
    return array.reshape(-1).view(np.uint8).data


class MeshStream:
    """Decodes the responses of DownloadMesh, one at a time (feed()), into the MeshArrays that
    mesh() returns once the stream has ended; `report` gets the fraction of the bytes received
    after each chunk (it may raise, to stop the download)."""

    def __init__(self, report: Callable[[float], Any]) -> None:
        self._report = report
        self._mesh: MeshArrays | None = None
        self._buffers: list[memoryview] = []
        self._array = 0  # the buffer being filled
        self._offset = 0  # its next byte
        self._received = 0
        self._total = 0

    def feed(self, response: pb.DownloadMeshResponse) -> None:
        which = response.WhichOneof("payload")
        if which == "header":
            self._start(response.header)
        elif which == "chunk":
            self._chunk(response.chunk)

    def _start(self, header: pb.UploadMeshHeader) -> None:
        if self._mesh is not None:
            raise ActopoError("DownloadMesh: a second header")
        vertices, tetrahedra = header.num_vertices, header.num_tetrahedra
        if vertices < 0 or tetrahedra < 0:
            raise ActopoError(f"DownloadMesh: {vertices} vertices and {tetrahedra} tetrahedra "
                              "in the header")
        points = _array((vertices, 3), header.points_dtype, "points", "f")
        tets = _array((tetrahedra, 4), header.tetrahedra_dtype, "tetrahedra", "i")
        data = {f.name: _array((vertices,), f.dtype, f"field '{f.name}'", "fi")
                for f in header.fields}
        if len(data) != len(header.fields):
            raise ActopoError("DownloadMesh: a field named twice in the header")
        times = {f.name: f.time for f in header.fields if f.HasField("time")}
        self._mesh = MeshArrays(header.name, points, tets, data, times)
        self._buffers = [_bytes(a) for a in (points, tets, *data.values())]
        self._total = sum(len(b) for b in self._buffers)

    def _chunk(self, chunk: bytes) -> None:
        if self._mesh is None:
            raise ActopoError("DownloadMesh: a chunk before the header")
        rest = memoryview(chunk)
        while len(rest):
            while self._array < len(self._buffers) and \
                    self._offset == len(self._buffers[self._array]):
                self._array, self._offset = self._array + 1, 0
            if self._array == len(self._buffers):
                raise ActopoError(f"DownloadMesh: more than the {self._total} bytes the header "
                                  "announced")
            buffer = self._buffers[self._array]
            take = min(len(rest), len(buffer) - self._offset)
            buffer[self._offset:self._offset + take] = rest[:take]
            self._offset += take
            rest = rest[take:]
        self._received += len(chunk)
        self._report(self._received / self._total if self._total else 1.0)

    def mesh(self) -> MeshArrays:
        """The mesh, once every byte the header announced has arrived."""
        if self._mesh is None:
            raise ActopoError("DownloadMesh: the stream ended without its header")
        if self._received != self._total:
            raise ActopoError(f"DownloadMesh: the stream ended after {self._received} of the "
                              f"{self._total} bytes the header announced")
        return self._mesh
