"""Uploads of mesh files as their bytes (CreateUpload, WriteUpload, GetUpload, DeleteUpload,
then LoadMesh with source `upload`): what a file upload sends and how it goes on after a broken
connection. No calls here: Client.upload_file() and AsyncClient.upload_file() make them, and
share these decisions.

    files = upload_plan("wave.vtu")           # hashed (a .pvd: with the files it names)
    sender = Sender(files, retries=True)
    status = CreateUpload(create_request(files)).upload
    where = sender.next_write(status)         # (file, offset), None once all is held
    while where is not None:
        try:
            status = WriteUpload(sender.requests(status.upload_id, *where)).upload
            where = sender.next_write(status, wrote=True)
        except grpc.RpcError as e:
            time.sleep(sender.failed(e))      # raises when the error is definitive
            where = sender.next_write(GetUpload(status.upload_id).upload)  # what it holds

A file is read twice, in chunks of CHUNK_BYTES: once to hash it (the server checks each file's
SHA-256 at its last byte), once to send it; the client holds one chunk at a time, whatever the
file's size. The server keeps every chunk it has appended when a connection breaks (the last
one in flight may be lost), so the client asks what it holds and sends from there: an upload
cut anywhere sends its bytes about once.
"""

from __future__ import annotations

import hashlib
import os
import random
import threading
import time
import xml.etree.ElementTree as ElementTree
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

import grpc

from actopo._channel import RETRY_POLICY
from actopo._errors import ActopoError, InvalidArgumentError, InvalidMeshError, translate
from actopo._progress import Progress
from actopo._proto import pb
from actopo._types import LoadProgress

CHUNK_BYTES = 1 << 20
"""Bytes of a WriteUpload chunk, and of a read when hashing."""
MESH_FILES = (".vtu", ".vtk", ".vti", ".pvd")
"""The files the server reads as they are (its data directory's formats), by extension."""
PROGRESS_SECONDS = 0.1
"""How often the blocking client reports the bytes sent (the asyncio one: after each chunk)."""
DELETE_SECONDS = 5.0
"""Deadline of the DeleteUpload that a failed or interrupted upload sends."""
DEFINITIVE = frozenset({
    grpc.StatusCode.INVALID_ARGUMENT, grpc.StatusCode.DATA_LOSS, grpc.StatusCode.NOT_FOUND,
    grpc.StatusCode.RESOURCE_EXHAUSTED, grpc.StatusCode.FAILED_PRECONDITION,
    grpc.StatusCode.UNAUTHENTICATED, grpc.StatusCode.PERMISSION_DENIED,
    grpc.StatusCode.UNIMPLEMENTED, grpc.StatusCode.ALREADY_EXISTS,
    grpc.StatusCode.OUT_OF_RANGE,
})
"""WriteUpload's answers that sending again cannot change: the upload fails with them. Any other
(UNAVAILABLE, CANCELLED by the transport, DEADLINE_EXCEEDED, INTERNAL, ...) ends the stream
but not the upload: the client asks what the server holds and goes on."""
_RESUMABLE_PRECONDITIONS = ("but the server holds",)
"""The FAILED_PRECONDITION answers of WriteUpload that a resumption resolves: an offset past
what the server holds (asked before the server had dropped what a broken stream left)."""


def is_mesh_file(path: str | os.PathLike[str]) -> bool:
    """Whether `path` names a file the server reads as it is (.vtu, .vtk, .vti, .pvd)."""
    return Path(path).suffix.lower() in MESH_FILES


@dataclass(frozen=True)
class LocalFile:
    """A file of an upload: where it is here, its path in the upload, its size and SHA-256."""

    path: Path
    name: str
    size: int
    sha256: str


def _hash(path: Path) -> tuple[int, str]:
    """The file's size and SHA-256, read in chunks."""
    digest = hashlib.sha256()
    size = 0
    with path.open("rb") as f:
        while chunk := f.read(CHUNK_BYTES):
            digest.update(chunk)
            size += len(chunk)
    return size, digest.hexdigest()


def _relative(pvd: Path, index: int, file: str) -> str:
    """The path a .pvd's DataSet `index` names, as the upload names it: relative to the .pvd's
    folder, '/' between parts, '.' parts left out. Absolute paths and '..' parts are refused:
    an upload holds the .pvd's folder and what lies under it."""
    if not file:
        raise InvalidMeshError(f"{pvd}: DataSet {index} has no file attribute")
    parts = [p for p in PurePosixPath(file).parts if p != "."]
    if file.startswith(("/", "\\")) or "\\" in file or (len(file) > 1 and file[1] == ":") \
            or ".." in parts or not parts:
        raise InvalidArgumentError(
            f"{pvd}: DataSet {index} names '{file}', which is not a relative path under the "
            ".pvd's folder: an upload takes the files beside the .pvd and below it (copy the "
            "files there and name them relative to it)")
    return "/".join(parts)


def pvd_files(pvd: Path) -> list[str]:
    """The files a ParaView collection names (its DataSet elements' `file` attributes, in
    order, each once), relative to its folder; see _relative() for what is refused."""
    try:
        root = ElementTree.parse(pvd).getroot()
    except ElementTree.ParseError as e:
        raise InvalidMeshError(f"{pvd}: not a ParaView collection (.pvd: {e})") from None
    collection = root.find("Collection") if root.tag == "VTKFile" else None
    if collection is None:
        raise InvalidMeshError(f"{pvd}: not a ParaView collection (.pvd: a VTKFile element "
                               "with a Collection)")
    names = [_relative(pvd, k, data_set.get("file", ""))
             for k, data_set in enumerate(collection.findall("DataSet"))]
    if not names:
        raise InvalidMeshError(f"{pvd}: the collection lists no DataSet")
    return list(dict.fromkeys(names))


def upload_name(path: Path, name: str | None) -> str:
    """The mesh file's path in the upload, which the server names the mesh by: `name`, else
    the file's name. The server reads a file by its extension, so a name without the file's
    gets it ("wave" for wave.vtu: "wave.vtu")."""
    if name is None:
        return path.name
    if not name or "/" in name or "\\" in name or name in (".", ".."):
        raise InvalidArgumentError(f"name: '{name}' is not a file name (no '/' or '\\')")
    suffix = path.suffix
    return name if name.lower().endswith(suffix.lower()) else name + suffix


def upload_plan(path: str | os.PathLike[str], name: str | None = None) -> list[LocalFile]:
    """The files of an upload of the mesh file `path`: the file itself first, under `name`
    (upload_name()), then for a .pvd each file it names, under the path the .pvd names it by;
    each hashed (read once). FileNotFoundError for a missing file, naming the .pvd's entry for
    one of its files; InvalidArgumentError for a file the server does not read as it is."""
    mesh = Path(path)
    if not mesh.is_file():
        raise FileNotFoundError(f"no such mesh file: {mesh}")
    if not is_mesh_file(mesh):
        raise InvalidArgumentError(
            f"{mesh}: the server reads {', '.join(MESH_FILES)} files as they are; upload "
            "other formats with upload_mesh(), which reads them with pyvista or meshio")
    names = [(mesh, upload_name(mesh, name))]
    if mesh.suffix.lower() == ".pvd":
        for k, relative in enumerate(pvd_files(mesh)):
            local = mesh.parent / relative
            if not local.is_file():
                raise FileNotFoundError(f"{mesh}: file {k} of the collection, '{relative}', is "
                                        f"not there ({local})")
            names.append((local, relative))
    return [LocalFile(local, upload, *_hash(local)) for local, upload in names]


def create_request(files: list[LocalFile]) -> pb.CreateUploadRequest:
    return pb.CreateUploadRequest(files=[pb.UploadFileInfo(path=f.name, size=f.size,
                                                           sha256=f.sha256) for f in files])


def resumable(error: grpc.RpcError) -> bool:
    """Whether a failed WriteUpload leaves an upload to go on with (see DEFINITIVE)."""
    code = error.code() if hasattr(error, "code") else grpc.StatusCode.UNKNOWN
    if code == grpc.StatusCode.FAILED_PRECONDITION:
        details = error.details() if hasattr(error, "details") else ""
        return any(cause in (details or "") for cause in _RESUMABLE_PRECONDITIONS)
    return code not in DEFINITIVE


def backoff(retry: int) -> float:
    """Seconds before resumption `retry` (1, 2, ...): the channel's retry policy
    (_channel.RETRY_POLICY), 0.2, 0.4, 0.8, 1.6 s, at most 2 s, each +-20% as gRPC's jitter."""
    initial = float(RETRY_POLICY["initialBackoff"].rstrip("s"))
    most = float(RETRY_POLICY["maxBackoff"].rstrip("s"))
    delay = min(most, initial * float(RETRY_POLICY["backoffMultiplier"]) ** (retry - 1))
    return delay * random.uniform(0.8, 1.2)


class Sender:
    """One upload's sending: which file and offset to write next, the requests of a WriteUpload
    call (the file read from disk chunk by chunk as gRPC takes them), and what a failed call
    means. `retries`: resume after a broken stream, up to RETRY_POLICY's maxAttempts calls in a
    row that move nothing forward (False: never).

    The requests may be iterated by gRPC's thread (the blocking client): they never raise
    there, where an error would only cancel the call; a read error stops them and check()
    raises it in the caller's thread. stop() ends them from any thread."""

    def __init__(self, files: list[LocalFile], retries: bool = True,
                 chunk_bytes: int = CHUNK_BYTES) -> None:
        self.files = files
        self.total = sum(f.size for f in files)
        self.sent_bytes = 0
        """Bytes of chunks handed to gRPC, resent ones included."""
        self._chunk_bytes = chunk_bytes
        self._attempts = int(RETRY_POLICY["maxAttempts"]) if retries else 1
        self._failures = 0
        self._held = -1
        self._position = 0
        self._shown = 0
        self._reported = False
        self._error: BaseException | None = None
        self._stopped = threading.Event()
        self._start = time.monotonic()

    def next_write(self, status: pb.UploadStatus,
                   wrote: bool = False) -> tuple[int, int] | None:
        """The file (its index) and offset to write from, after the server's `status` (`wrote`:
        the answer of a WriteUpload call that ended well); None once the server holds every
        byte. Bytes held beyond the last status start the count of failed attempts afresh."""
        if len(status.received_bytes) != len(self.files):
            raise ActopoError(f"upload '{status.upload_id}': the server describes "
                              f"{len(status.received_bytes)} files, not {len(self.files)}")
        held = sum(status.received_bytes)
        if wrote and held <= self._held and not status.complete:
            raise ActopoError(f"upload '{status.upload_id}': a WriteUpload call ended well, but "
                              f"the server holds {held} of the {self.total} bytes, as before it")
        if held > self._held:
            self._failures = 0
        self._held = held
        self._position = held
        for k, (f, received) in enumerate(zip(self.files, status.received_bytes, strict=True)):
            if received < f.size:
                return k, received
        return None

    def requests(self, upload_id: str, file: int,
                 offset: int) -> Iterator[pb.WriteUploadRequest]:
        """A WriteUpload call's messages: the start, then the file's bytes from `offset` in
        chunks, each read as gRPC asks for it."""
        yield pb.WriteUploadRequest(start=pb.WriteUploadStart(upload_id=upload_id, file=file,
                                                              offset=offset))
        local = self.files[file]
        try:
            with local.path.open("rb") as f:
                f.seek(offset)
                left = local.size - offset
                while left > 0 and not self._stopped.is_set():
                    chunk = f.read(min(self._chunk_bytes, left))
                    if not chunk:
                        raise ActopoError(f"{local.path}: the file is shorter than when it was "
                                          f"hashed ({local.size} bytes); upload it again")
                    left -= len(chunk)
                    self.sent_bytes += len(chunk)
                    self._position += len(chunk)
                    yield pb.WriteUploadRequest(chunk=chunk)
        except (OSError, ActopoError) as e:
            self._error = e

    def check(self) -> None:
        """Raises what stopped the requests (a file that could not be read), if anything."""
        if self._error is not None:
            raise self._error

    def stop(self) -> None:
        """Ends the requests at their next chunk."""
        self._stopped.set()

    def failed(self, error: grpc.RpcError) -> float:
        """After a failed WriteUpload: the seconds to wait before asking the server what it
        holds and going on, or the client's error raised when the failure is definitive or the
        attempts are spent."""
        self.check()
        if not resumable(error):
            raise translate(error) from None
        self._failures += 1
        if self._failures >= self._attempts:
            failure = translate(error)
            if self._attempts > 1:
                failure = type(failure)(f"{failure.details} (the upload stopped after "
                                        f"{self._attempts} attempts that sent nothing more)",
                                        failure.code)
            raise failure from None
        return backoff(self._failures)

    def report(self, bar: Progress[LoadProgress]) -> None:
        """The bytes sent, to the upload's progress bar or callable, when they moved."""
        report = self.progress()
        if report is not None:
            bar.update(report)

    def progress(self) -> LoadProgress | None:
        """The "send" phase's report when the bytes sent went forward since the last one:
        the bytes the server holds and those sent after them (never going back, even where a
        resumption sends again a chunk lost in flight)."""
        done = min(max(self._position, self._shown), self.total)
        if self._reported and done == self._shown:
            return None
        self._shown, self._reported = done, True
        return LoadProgress("send", done / self.total if self.total else 1.0,
                            time.monotonic() - self._start, sent_bytes=done,
                            total_bytes=self.total)


def description(files: list[LocalFile]) -> str:
    """What the progress bars of a file upload say: "upload NAME" (with "+N files" for a
    .pvd's)."""
    others = len(files) - 1
    more = f" +{others} file{'s' if others > 1 else ''}" if others > 0 else ""
    return f"upload {files[0].name}{more}"


def build_load_upload(upload_id: str, partition: pb.PartitionOptions) -> pb.LoadMeshRequest:
    return pb.LoadMeshRequest(upload=upload_id, partition=partition)
