"""The blocking client: Client, Session and Job."""

from __future__ import annotations

import contextlib
import os
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from typing import TYPE_CHECKING, Any, TypeVar

import grpc
import numpy as np
import numpy.typing as npt

from actopo import _batches, _file_upload, _messages, _requests
from actopo._batches import Piece
from actopo._channel import (
    DEFAULT_TIMEOUT,
    MESH_TIMEOUT,
    OWN_CONNECTION,
    TlsArg,
    client_metadata,
    resolve_target,
    sync_channel,
)
from actopo._distances import DistanceMatrix
from actopo._download import MeshStream
from actopo._errors import ActopoError, translate, translated
from actopo._fields import FieldsLike, TimesArg
from actopo._file_upload import LocalFile, Sender
from actopo._literals import Algorithm, Precompute, Prefetch, Relation, Structure
from actopo._mesh import MeshArrays, MeshLike
from actopo._progress import (
    LoadProgressArg,
    Progress,
    ProgressArg,
    make_fraction_progress,
    make_load_progress,
    make_progress,
)
from actopo._proto import pb
from actopo._requests import (
    FieldsArg,
    MeshRef,
    MeshSource,
    SimplexArg,
    SimplexIds,
    distance_parameters,
    partition,
)
from actopo._results import Assembler, FieldResult, JobResult, distance_matrix_of
from actopo._stub import ResponseStream, sync_stub
from actopo._types import (
    UPLOAD_PHASES,
    JobProgress,
    LoadProgress,
    MeshInfo,
    RelationBatch,
    ServerInfo,
    SessionInfo,
    SessionStats,
    SimplexRelation,
    StreamItem,
)

if TYPE_CHECKING:
    from typing_extensions import Self

_Request = TypeVar("_Request")
_Response = TypeVar("_Response")


class Client:
    """A connection to an actopo-server.

    Args:
        target: "HOST:PORT"; defaults to $ACTOPO_SERVER.
        token: a bearer token sent with every call (``authorization`` metadata).
        affinity_key: sent with every call as ``x-actopo-session``; behind a load balancer that
            hashes it (deploy/haproxy.cfg), all calls of this client reach one server replica,
            where its meshes and sessions live. Defaults to $ACTOPO_AFFINITY_KEY, else a fresh
            random key per client.
        tls: False for plaintext, True for TLS with the system's roots, or your own
            ``grpc.ChannelCredentials``.
        timeout: deadline in seconds of quick calls; loading, uploading and opening sessions get
            600 s, jobs none (Ctrl-C cancels them). None: no deadlines at all.
        options: extra gRPC channel options, e.g. ``[("grpc.max_receive_message_length", n)]``;
            they replace the client's own of the same name.
        retries: True (the default) retries the idempotent reads (server_info, list_meshes,
            get_mesh, list_sessions, get_session, and on a session stats, query and relation
            up to one batch) when they end UNAVAILABLE, e.g. while the server restarts:
            5 attempts over about 3 s, within the call's deadline, and resumes a file upload
            (upload_file) whose connection broke, with the same attempts and backoff. Nothing
            else is retried. False: no retries (see actopo._channel).

    Example::

        import actopo

        with actopo.Client("127.0.0.1:50051") as client:
            mesh = client.load_mesh("fertility_tet.vtu")
            with client.open_session(mesh, scalar="eigenfunction4") as session:
                result = session.run("morse-smale", progress=True)
            print(result.summary["critical_cells"], result.stats.run_seconds)
    """

    def __init__(self, target: str | None = None, *, token: str | None = None,
                 affinity_key: str | None = None,
                 tls: TlsArg = False, timeout: float | None = DEFAULT_TIMEOUT,
                 options: Sequence[tuple[str, Any]] = (), retries: bool = True) -> None:
        self.target = resolve_target(target)
        self._channel = sync_channel(self.target, tls, options, retries)
        self._stub = sync_stub(self._channel)
        self.affinity_key, self._metadata = client_metadata(token, affinity_key)
        self._timeout = timeout
        self._mesh_timeout = MESH_TIMEOUT if timeout is not None else None
        self._max_batch: int | None = None
        self._retries = retries
        self._channel_args = (tls, tuple(options))

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Closes the channel (sessions stay open on the server until closed or idle)."""
        self._channel.close()

    def __repr__(self) -> str:
        return f"actopo.Client({self.target!r})"

    def _call(self, rpc: grpc.UnaryUnaryMultiCallable[_Request, _Response], request: _Request,
              *, long: bool = False, mesh: bool = False) -> _Response:
        """A unary call with this client's metadata and deadline (`long`: that of loading,
        uploading and opening sessions); `mesh` marks calls whose argument is a mesh, so that
        INVALID_ARGUMENT raises InvalidMeshError."""
        with translated(mesh=mesh):
            return rpc(request, timeout=self._mesh_timeout if long else self._timeout,
                       metadata=self._metadata)

    # Server.

    def server_info(self) -> ServerInfo:
        """Versions, algorithms, relations, samples and limits of the server.

        >>> client.server_info().algorithms
        ['topo-relations', 'critical-points', 'discrete-gradient', 'morse-smale',
         'persistence-diagram', 'topological-simplification', 'diagram-distance', 'tracking',
         'merge-tree', 'contour-tree']
        """
        response = self._call(self._stub.GetServerInfo, _messages.build_get_server_info())
        info = _messages.decode_get_server_info(response)
        self._max_batch = _messages.max_batch(info)
        return info

    def _batch_size(self) -> int:
        if self._max_batch is None:
            self.server_info()
        return self._max_batch or _requests.DEFAULT_BATCH

    # Meshes.

    def load_mesh(self, path: MeshSource, *, times: Sequence[float] | None = None,
                  block_size: int = 0, block_label_field: str = "",
                  progress: LoadProgressArg = None) -> MeshInfo:
        """Loads a file under the server's data directory ("sample:NAME" loads a sample), or a
        series given as the list of its files.

        path: a file (a .pvd collection too) relative to the data directory; "sample:NAME";
        or a list of files with the same points and tetrahedra in the same order, in step
        order, which load as one mesh, as a .pvd of them would: each file's point fields
        become ``<field>_<k>``, k the file's index zero-padded to the width of the last
        (``velocityMag_0`` ... ``velocityMag_3``; with 12 files ``_00`` ... ``_11``). The
        server's errors name the file as ``files.paths[k]`` (NotFoundError for a missing one),
        or as ``files: step k`` for one whose points or tetrahedra differ from the first's
        (InvalidMeshError).
        times: with a list, each file's time value (``FieldInfo.time``; default: k); a length
        other than the list's raises InvalidArgumentError naming ``times``.
        block_size: octree bucket capacity (max vertices per block; 0: the server's 1000);
        block_label_field: partition by this integer point field instead.
        progress: True for a bar on stderr per phase of the load ("read", "partition",
        "encode"), or a callable receiving a LoadProgress(phase, fraction, elapsed_seconds);
        None or False for no progress. Ctrl-C, or an exception raised by the callable, stops
        the load on the server (which frees what it built) and propagates.

        >>> reports = []
        >>> info = client.load_mesh("sample:jittered:4", progress=reports.append)
        >>> list(dict.fromkeys(r.phase for r in reports))  # the phases, in order
        ['read', 'partition', 'encode']
        >>> client.delete_mesh(info)
        >>> series = client.load_mesh(["isabel_series_s2/isabel_02_s2_tet.vtu",
        ...                            "isabel_series_s2/isabel_03_s2_tet.vtu"], times=[2, 3])
        >>> [(f.name, f.time) for f in series.fields]
        [('velocityMag_0', 2.0), ('velocityMag_1', 3.0)]
        >>> client.delete_mesh(series)
        """
        request = _messages.build_load_mesh(path, block_size, block_label_field, times)
        if progress:
            return self._load_reporting(
                request, make_load_progress(progress, _messages.load_description(request)))
        response = self._call(self._stub.LoadMesh, request, long=True, mesh=True)
        return _messages.decode_load_mesh(response)

    def _load_reporting(self, request: pb.LoadMeshRequest,
                        bar: Progress[LoadProgress]) -> MeshInfo:
        """LoadMeshWithProgress: reports each progress message to `bar`."""
        stream = _messages.LoadStream(bar.update)
        call = self._stub.LoadMeshWithProgress(_messages.build_load_mesh_with_progress(request),
                                               timeout=self._mesh_timeout,
                                               metadata=self._metadata)
        try:
            with translated(mesh=True):
                for response in call:
                    stream.feed(response)
        finally:
            call.cancel()  # stops the load after Ctrl-C or a raising callback; else a no-op
            bar.close()
        return stream.mesh()

    def sample(self, name: str, *, block_size: int = 0,
               progress: LoadProgressArg = None) -> MeshInfo:
        """Loads a built-in sample, e.g. "wavelet:64" or "jittered:100"; `progress` as for
        load_mesh()."""
        return self.load_mesh(f"sample:{name}", block_size=block_size, progress=progress)

    def upload_mesh(self, mesh: MeshLike, *, name: str | None = None, block_size: int = 0,
                    block_label_field: str = "",
                    compression: grpc.Compression | None = None) -> MeshInfo:
        """Uploads a local mesh.

        `mesh`: a pyvista.UnstructuredGrid, a meshio.Mesh, a file path, or ``(points,
        tetrahedra)`` / ``(points, tetrahedra, {name: values})`` numpy arrays. A .vtu, .vtk,
        .vti or .pvd file goes as its bytes, as upload_file() sends it (the server reads it;
        a server from before file uploads, which answers UNIMPLEMENTED, gets its arrays);
        another file is read with pyvista or meshio and goes as arrays, as meshes in memory
        do. Arrays: only tetrahedra are accepted, anything else raises InvalidMeshError before
        a byte is sent; scalar point fields travel along, vector fields are left out; the
        tetrahedra go as int32 when the ids fit. `compression`: e.g. grpc.Compression.Gzip to
        compress the arrays on the wire (off by default: on a fast link it costs more time
        than it saves; it does not apply to a file, whose bytes VTK has compressed already).

        >>> import numpy as np
        >>> points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
        >>> info = client.upload_mesh((points, [[0, 1, 2, 3]], {"h": points[:, 2]}))
        >>> info.vertices, info.tetrahedra, info.edges  # edges and triangles: on first need
        (4, 1, None)
        >>> counted = client.get_mesh(info, count_faces=True)
        >>> counted.edges, counted.triangles
        (6, 4)
        >>> client.delete_mesh(info)
        """
        if isinstance(mesh, (str, os.PathLike)) and _file_upload.is_mesh_file(mesh):
            try:
                return self.upload_file(mesh, name=name, block_size=block_size,
                                        block_label_field=block_label_field)
            except ActopoError as e:  # a server from before file uploads: the arrays, as then
                if e.code != grpc.StatusCode.UNIMPLEMENTED:
                    raise
        requests = _messages.build_upload_mesh(mesh, name, block_size, block_label_field)
        with translated(mesh=True):
            response = self._stub.UploadMesh(requests, timeout=self._mesh_timeout,
                                             metadata=self._metadata, compression=compression)
        return _messages.decode_upload_mesh(response)

    def upload_file(self, path: str | os.PathLike[str], *, name: str | None = None,
                    block_size: int = 0, block_label_field: str = "",
                    progress: LoadProgressArg = None) -> MeshInfo:
        """Uploads a mesh file as its bytes and loads it, as the server loads a file of its data
        directory (the same readers and limits); the mesh is named after the file.

        `path`: a .vtu, .vtk or .vti file, or a .pvd with the files it names (relative to its
        folder, at or below it: an absolute path or '..' raises InvalidArgumentError naming the
        entry; a missing one FileNotFoundError). `name`: the mesh's name instead of the file's
        (the file's extension is added if missing: the server reads the file by it).
        `block_size`, `block_label_field`: as for load_mesh(). `progress`: True for a bar on
        stderr counting the bytes sent, then one per phase of the load, or a callable receiving
        LoadProgress reports: phase "send" (with ``sent_bytes`` and ``total_bytes``), then
        "read", "partition" and "encode".

        Each file is read twice, in 1 MiB chunks: once for its SHA-256, announced before a byte
        is sent (CreateUpload), once to send it (WriteUpload); the client holds one chunk at a
        time, whatever the size. The server checks each file's digest at its last byte. A
        connection that breaks mid-way (UNAVAILABLE, a reset stream, a deadline) loses nothing
        the server has written: the client asks what it holds (GetUpload) and sends from there,
        up to 5 times in a row without progress, backing off 0.2 s to 2 s as the retries of
        reads do (``retries=False``: never). A definitive error, Ctrl-C or an exception raised
        by the callable deletes the upload on the server and propagates: DataLossError (the
        bytes do not hash to the announced digest, e.g. the file changed meanwhile),
        ResourceExhaustedError (the server's upload budget, ``limits.upload_budget_bytes``, or
        ``max_uploads``), InvalidMeshError (a file the server cannot read, naming it). Loading
        the upload takes it off the server, whether the load succeeds or not.
        """
        options = partition(block_size, block_label_field)
        files = _file_upload.upload_plan(path, name)
        bar = make_load_progress(progress, _file_upload.description(files), UPLOAD_PHASES)
        try:
            upload_id = self._send_files(files, bar)
        except BaseException:
            bar.close()
            raise
        try:
            return self._load_reporting(_file_upload.build_load_upload(upload_id, options), bar)
        except BaseException:
            # The server drops an upload it has begun to load; one stopped before (Ctrl-C while
            # the load waits for a thread) would stay until the server's upload timeout.
            self._delete_upload(upload_id)
            raise

    def _send_files(self, files: list[LocalFile], bar: Progress[LoadProgress]) -> str:
        """CreateUpload, then the files' bytes until the server holds them all; the upload's
        id. Whatever stops it deletes the upload (best effort) and propagates."""
        created = self._call(self._stub.CreateUpload, _file_upload.create_request(files),
                             long=True)
        try:
            self._send(Sender(files, self._retries), created.upload, bar)
        except BaseException:
            self._delete_upload(created.upload.upload_id, own_connection=True)
            raise
        return created.upload.upload_id

    def _send(self, sender: Sender, status: pb.UploadStatus, bar: Progress[LoadProgress]) -> None:
        """WriteUpload calls from what the server holds (`status`) until it holds every byte;
        after a broken call, GetUpload says where to go on (Sender.failed() decides whether
        and when)."""
        upload_id = status.upload_id
        where = sender.next_write(status)
        sender.report(bar)
        while where is not None:
            try:
                status = self._write_upload(sender, upload_id, *where, bar)
                where = sender.next_write(status, wrote=True)
            except grpc.RpcError as e:
                where = sender.next_write(self._resume(sender, upload_id, e))
        sender.report(bar)

    def _write_upload(self, sender: Sender, upload_id: str, file: int, offset: int,
                      bar: Progress[LoadProgress]) -> pb.UploadStatus:
        """One WriteUpload call: the chunks from `offset` to the end of file `file`, read as
        gRPC's thread sends them, while this thread reports the bytes sent."""
        call = self._stub.WriteUpload.future(sender.requests(upload_id, file, offset),
                                             timeout=self._mesh_timeout,
                                             metadata=self._metadata)
        try:
            while True:
                try:
                    response = call.result(timeout=_file_upload.PROGRESS_SECONDS)
                    break
                except grpc.FutureTimeoutError:
                    sender.report(bar)
        except grpc.RpcError:
            raise
        except BaseException:
            sender.stop()
            call.cancel()  # after Ctrl-C or a raising callback
            raise
        sender.check()
        sender.report(bar)
        return response.upload

    def _resume(self, sender: Sender, upload_id: str,
                error: grpc.RpcError) -> pb.UploadStatus:
        """What the server holds of the upload after the failed call that raised `error`,
        asked after Sender.failed()'s delay (again while the server cannot be reached)."""
        while True:
            time.sleep(sender.failed(error))
            try:
                return self._stub.GetUpload(pb.GetUploadRequest(upload_id=upload_id),
                                            timeout=self._timeout,
                                            metadata=self._metadata).upload
            except grpc.RpcError as e:
                error = e

    def _delete_upload(self, upload_id: str, *, own_connection: bool = False) -> None:
        """Drops an upload on the server, if it can be reached and still has it.

        `own_connection`: sent on a connection of its own, for a stopped WriteUpload: what that
        call had handed to the client's connection (up to the server's flow-control window, a
        few MiB) goes out before anything sent after it, seconds on a slow link."""
        request = pb.DeleteUploadRequest(upload_id=upload_id)
        with contextlib.ExitStack() as stack, contextlib.suppress(grpc.RpcError):
            stub = self._stub
            if own_connection:
                tls, options = self._channel_args
                stub = sync_stub(stack.enter_context(sync_channel(
                    self.target, tls, [*options, OWN_CONNECTION], self._retries)))
            # wait_for_ready: after a cut connection the channel reconnects within the timeout
            # instead of failing at once.
            stub.DeleteUpload(request, timeout=_file_upload.DELETE_SECONDS,
                              metadata=self._metadata, wait_for_ready=True)

    def download_mesh(self, mesh: MeshRef, fields: FieldsArg = None, *,
                      progress: ProgressArg = None) -> MeshArrays:
        """A loaded mesh as the server holds it: its points in input order, its tetrahedra as
        given (each one's vertices in their order), and the point fields asked for, in the
        upload's format. What it returns, a MeshArrays, upload_mesh() takes back as it is, and
        its to_pyvista() and to_meshio() make a pyvista grid and a meshio mesh of it; pass it
        as `mesh` to JobResult.write() or to_pyvista() for the per-vertex results.

        `fields`: None (the default) for none, a list of names (in that order), or "all" for
        every point field of the mesh in its order. Each field keeps the dtype it was loaded
        or added with (float32, float64, int32 or int64) and its time value (``times``); the
        server holds the values as float64, so int64 values beyond 2**53 come back rounded.
        The points come as float64, the tetrahedra as int32 (int64 past 2**31 vertices).
        `progress`: True for a bar on stderr, or a callable receiving the fraction of the
        bytes received; Ctrl-C, or an exception raised by the callable, stops the download.

        The bytes arrive in chunks of about 1 MiB, copied into arrays allocated from the
        first message: the mesh is held once. NotFoundError for an unknown mesh or field
        (naming ``fields[i]`` and listing the mesh's fields), InvalidArgumentError for a field
        named twice.

        >>> info = client.upload_mesh((np.eye(4, 3), [[0, 3, 1, 2]], {"h": np.arange(4.0)}))
        >>> mesh = client.download_mesh(info, "all")
        >>> mesh
        MeshArrays('arrays', 4 vertices, 1 tetrahedra, fields ['h'])
        >>> mesh.tetrahedra, mesh.point_data["h"]
        (array([[0, 3, 1, 2]], dtype=int32), array([0., 1., 2., 3.]))
        >>> client.delete_mesh(info)
        """
        request = _messages.build_download_mesh(mesh, fields)
        bar = make_fraction_progress(progress, _messages.download_description(mesh))
        stream = MeshStream(bar.update)
        call = self._stub.DownloadMesh(request, timeout=self._mesh_timeout,
                                       metadata=self._metadata)
        try:
            with translated():
                for response in call:
                    stream.feed(response)
        finally:
            call.cancel()  # stops the download after Ctrl-C or a raising callback
            bar.close()
        return stream.mesh()

    def list_meshes(self) -> list[MeshInfo]:
        """The meshes loaded on the server."""
        response = self._call(self._stub.ListMeshes, _messages.build_list_meshes())
        return _messages.decode_list_meshes(response)

    def get_mesh(self, mesh: MeshRef, *, count_faces: bool = False) -> MeshInfo:
        """Describes one mesh (by MeshInfo or id).

        With count_faces the server first builds the mesh's edges and triangles if it has not
        yet (about a second per 10M tetrahedra), so that ``edges`` and ``triangles`` are set.
        """
        response = self._call(self._stub.GetMesh, _messages.build_get_mesh(mesh, count_faces),
                              long=count_faces)
        return _messages.decode_get_mesh(response)

    def delete_mesh(self, mesh: MeshRef) -> None:
        """Deletes a mesh; the server frees it once no session uses it."""
        self._call(self._stub.DeleteMesh, _messages.build_delete_mesh(mesh))

    # Fields.

    def add_fields(self, mesh: MeshRef, fields: FieldsLike, *,
                   times: TimesArg = None) -> MeshInfo:
        """Adds point fields to a loaded mesh and returns the mesh with them.

        `fields`: a mapping name -> values, one per vertex (float32 values are kept as
        float32, float64 as float64, integers become float64), or a pyvista dataset or a
        meshio.Mesh of the same vertices, whose scalar point fields are taken. A bad dtype,
        shape or length raises InvalidArgumentError naming the field before anything is sent.
        `times`: the fields' time values (series members), by name or one per field in order;
        they come back as ``FieldInfo.time``.

        The values go over one AddFields call in 1 MiB chunks, each field in turn, with their
        SHA-256. All or nothing: the server adds every field or none. It raises
        AlreadyExistsError for a name the mesh has, InvalidArgumentError for an empty or
        repeated name or a non-finite value (naming ``fields[i]``), NotFoundError for an
        unknown mesh, ResourceExhaustedError past its memory budget.

        >>> info = client.upload_mesh((np.eye(4, 3), [[0, 1, 2, 3]], {"h": np.arange(4.0)}))
        >>> info = client.add_fields(info, {"x": np.arange(4), "y": np.ones(4, np.float32)},
        ...                          times=[0.5, 1.5])
        >>> [(f.name, f.dtype, f.max, f.time) for f in info.fields]
        [('h', 'float64', 3.0, None), ('x', 'float64', 3.0, 0.5), ('y', 'float32', 1.0, 1.5)]
        >>> [f.name for f in client.delete_field(info, "x").fields]
        ['h', 'y']
        >>> client.delete_mesh(info)
        """
        requests = _messages.build_add_fields(mesh, fields, self._vertices(mesh), times)
        with translated():
            response = self._stub.AddFields(requests, timeout=self._mesh_timeout,
                                            metadata=self._metadata)
        return _messages.decode_add_fields(response)

    def add_field(self, mesh: MeshRef, name: str, values: npt.ArrayLike, *,
                  time: float | None = None) -> MeshInfo:
        """Adds one point field; see add_fields()."""
        return self.add_fields(mesh, {name: values}, times=None if time is None else [time])

    def delete_field(self, mesh: MeshRef, name: str) -> MeshInfo:
        """Deletes a point field of a mesh and returns the mesh without it (NotFoundError for
        an unknown mesh or field). Sessions and jobs that read it keep it until they are
        done."""
        response = self._call(self._stub.DeleteField, _messages.build_delete_field(mesh, name))
        return _messages.decode_delete_field(response)

    def _vertices(self, mesh: MeshRef) -> int:
        """The mesh's vertex count (asked of the server for a mesh given by id)."""
        return mesh.vertices if isinstance(mesh, MeshInfo) else self.get_mesh(mesh).vertices

    # Sessions.

    def open_session(self, mesh: MeshRef, *, scalar: str | None = None,
                     structure: Structure = "actopo", consumers: int = 0, producers: int = 0,
                     buffer_ratio: float = 0.0, prefetch: Prefetch = "auto",
                     precompute: Precompute = "auto", query_readers: int = 0) -> Session:
        """Opens a session: a structure ("explicit", "compact" or "actopo") on a mesh and a
        scalar field (default: the mesh's first floating-point field). 0 means the server's
        default (consumers and producers from the server's cores, as actopo-server --consumers
        0 documents; buffer ratio 0.2); prefetch "auto",
        "linear", "spatial" or "adaptive"; precompute "auto", "requested" or "declared".
        `query_readers`: relation calls answered at once on the session, each with a reader of
        its own (0: the server's default, one per server core, at most 4; the server allows
        1 to 64). Use it as a context manager to close it."""
        request = _messages.build_open_session(mesh, scalar, structure, consumers, producers,
                                               buffer_ratio, prefetch, precompute, query_readers)
        response = self._call(self._stub.OpenSession, request, long=True)
        return Session(self, _messages.decode_open_session(response))

    def session(self, session_id: str) -> Session:
        """A handle on an open session by id (e.g. one opened by the CLI)."""
        return Session(self, self.get_session(session_id))

    def get_session(self, session_id: str) -> SessionInfo:
        """Describes one session."""
        response = self._call(self._stub.GetSession, _messages.build_get_session(session_id))
        return _messages.decode_get_session(response)

    def list_sessions(self) -> list[SessionInfo]:
        """The open sessions."""
        response = self._call(self._stub.ListSessions, _messages.build_list_sessions())
        return _messages.decode_list_sessions(response)

    def close_session(self, session_id: str) -> None:
        """Closes a session by id, cancelling its running job."""
        self._call(self._stub.CloseSession, _messages.build_close_session(session_id))

    def cancel_job(self, job_id: str) -> None:
        """Cancels a running job by id."""
        self._call(self._stub.CancelJob, _messages.build_cancel_job(job_id))


class Session:
    """A structure on a mesh and a scalar field; relation queries and jobs run on it.

    Example::

        with client.open_session(mesh, structure="compact") as session:
            offsets, values = session.relation("vertex_edges", [0, 1, 2])
            print(session.stats().engine.hit_rate)
    """

    def __init__(self, client: Client, info: SessionInfo) -> None:
        self._client = client
        self.info = info
        self.session_id = info.session_id

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return (f"actopo.Session({self.session_id!r}, mesh={self.info.mesh_id!r}, "
                f"structure={self.info.structure!r})")

    def close(self) -> None:
        """Closes the session on the server (idempotent)."""
        if self.session_id:
            session_id, self.session_id = self.session_id, ""
            self._client.close_session(session_id)

    def describe(self) -> SessionInfo:
        """The session as the server sees it now (running job, last use)."""
        self.info = self._client.get_session(self._id())
        return self.info

    def _id(self) -> str:
        if not self.session_id:
            raise ValueError("the session is closed")
        return self.session_id

    def relation(self, name: Relation, ids: SimplexIds, *,
                 raise_errors: bool = True) -> RelationBatch:
        """A relation of many simplices, as CSR numpy arrays ``(offsets, values)``.

        `name`: e.g. "vertex_edges", "edge_triangles", "tetrahedron_neighbors", "vertex_link";
        `ids`: simplex ids (vertices and tetrahedra: input ids; edges and triangles: the
        service's ids), or an (n, k) array of vertex tuples; int32 ids travel as int32. Up to
        one message of simplices (65536, or the server's max_batch_size if smaller) go in one
        GetRelationBatch call; more go over one StreamRelations call (see relation_batches()).

        A bad simplex raises (OutOfRangeError, NotFoundError, ...), unless `raise_errors` is
        False: then the others are answered, the failed ones get empty rows and are listed in
        ``errors`` by position.

        On two tetrahedra (0, 1, 2, 3) and (1, 2, 3, 4):

        >>> offsets, values = session.relation("vertex_star", [0, 1])
        >>> offsets
        array([0, 1, 3])
        >>> values[offsets[1]:offsets[2]]  # the tetrahedra around vertex 1
        array([0, 1])
        >>> batch = session.relation("vertex_star", [4, 7, 0], raise_errors=False)
        >>> batch.offsets, batch.errors[0].index, batch.errors[0].message
        (array([0, 1, 1, 2]), 1, 'ids[1]: vertex id 7 is outside [0, 5)')
        """
        values = _requests.simplex_array(ids)
        if _batches.in_one_call(values, raise_errors, self._client._batch_size()):
            return self._batch(_requests.relation(name), values)
        [batch] = self.relation_batches(name, [values], raise_errors=raise_errors)
        return batch

    def _batch(self, code: pb.Relation, values: np.ndarray) -> RelationBatch:
        """One GetRelationBatch call; `values` as simplex_array() gives them."""
        request = _messages.build_get_relation_batch(self._id(), code, values)
        response = self._client._call(self._client._stub.GetRelationBatch, request)
        return _messages.decode_get_relation_batch(response)

    def relation_batches(self, name: Relation, arrays: Iterable[SimplexIds], *,
                         chunk_size: int | None = None, window: int = _batches.STREAM_WINDOW,
                         raise_errors: bool = False) -> Iterator[RelationBatch]:
        """Streams one relation over many arrays of simplices on one StreamRelations call,
        yielding one RelationBatch per input array, in order, as its answers arrive.

        `arrays`: an iterable (possibly lazy, read from gRPC's sending thread) of numpy arrays
        of ids (int32 or int64; other integers are sent as int64) or of (n, k) vertex tuples.
        Each array is cut into messages of `chunk_size` simplices (default 65536, at most the
        server's max_batch_size); up to `window` messages are written ahead of the answers.

        A simplex that fails gets an empty row and a FailedItem in its batch's ``errors``, by
        position in its array, and the stream goes on; with `raise_errors` the first one
        raises instead. A message that fails as a whole (closed session, unknown relation,
        bad array) raises.

        >>> for batch in session.relation_batches("vertex_star", [[0, 1], np.array([4], np.int32)]):
        ...     print(batch.offsets, batch.values)
        [0 1 3] [0 0 1]
        [0 1] [1]
        """
        chunk = _batches.chunk_size(chunk_size, self._client._batch_size())
        messages = _batches.messages(self._id(), _requests.relation(name), arrays, chunk)
        feeder = _Feeder(messages, _batches.window_size(window))
        collector = _batches.Collector(raise_errors)
        call = self._client._stub.StreamRelations(iter(feeder), metadata=self._client._metadata)
        try:
            for response in call:
                batch = collector.add(feeder.answered(), response)
                if batch is not None:
                    yield batch
        except grpc.RpcError as e:
            feeder.check()
            raise translate(e) from None
        finally:
            feeder.close()
            call.cancel()
        feeder.check()

    def query(self, name: Relation, simplex: SimplexArg, *,
              include_vertices: bool = False) -> SimplexRelation:
        """A relation of one simplex, given by id or by its vertices (any order).

        With include_vertices, result edges and triangles come with their vertex tuples.

        >>> session.query("edge_triangles", (2, 1), include_vertices=True).vertices
        array([[0, 1, 2],
               [1, 2, 3],
               [1, 2, 4]])
        """
        request = _messages.build_get_relation(self._id(), name, simplex, include_vertices)
        response = self._client._call(self._client._stub.GetRelation, request)
        return _messages.decode_get_relation(response)

    def relations_stream(self, name: Relation, simplices: Iterable[SimplexArg], *,
                         raise_errors: bool = False) -> Iterator[StreamItem]:
        """Streams one relation over many simplices (StreamRelations), yielding a StreamItem
        per simplex as answers arrive. A bad simplex gets its own error and the stream goes
        on, unless raise_errors. `simplices` may be a lazy iterable."""
        call = self._client._stub.StreamRelations(
            _messages.build_stream_relations(self._id(), name, simplices),
            metadata=self._client._metadata)
        try:
            for response in call:
                yield _messages.decode_stream_relations(response, raise_errors)
        except grpc.RpcError as e:
            raise translate(e) from None
        finally:
            call.cancel()

    def submit(self, algorithm: Algorithm, *, parameters: Mapping[str, Any] | None = None,
               include_arrays: bool = True, trace: bool = False, digests: bool = False,
               timeout: float | None = None, fields: FieldsArg = None) -> Job:
        """Starts a job and returns once the server accepted it; see run()."""
        return self._submit(algorithm, parameters, include_arrays, trace, digests, timeout,
                            fields)

    def _submit(self, algorithm: Algorithm, parameters: Mapping[str, Any] | None,
                include_arrays: bool, trace: bool, digests: bool, timeout: float | None,
                fields: FieldsArg, keep_fields: bool = True) -> Job:
        request, name = _messages.build_run_job(self._id(), algorithm, parameters,
                                                include_arrays, trace, digests, fields)
        call = self._client._stub.RunJob(request, timeout=timeout,
                                         metadata=self._client._metadata)
        try:
            return Job(self._client, call, name, keep_fields)
        except KeyboardInterrupt:
            self._cancel_unnamed_job()
            raise

    def _cancel_unnamed_job(self) -> None:
        """Ctrl-C before RunJob's first answer (the job's id) reached us: the server may have
        started the job all the same, and its stream's cancellation alone can reach a busy
        server after a short job has ended. The session runs one job at a time, so the one it
        runs now is the one just asked for: CancelJob it (best effort, CANCEL_TIMEOUT_S each)."""
        stub, metadata = self._client._stub, self._client._metadata
        with contextlib.suppress(grpc.RpcError):
            info = stub.GetSession(_messages.build_get_session(self._id()),
                                   timeout=CANCEL_TIMEOUT_S, metadata=metadata)
            running = _messages.decode_get_session(info).running_job_id
            if running:
                stub.CancelJob(_messages.build_cancel_job(running), timeout=CANCEL_TIMEOUT_S,
                               metadata=metadata)

    def run(self, algorithm: Algorithm, *, parameters: Mapping[str, Any] | None = None,
            progress: ProgressArg = False, include_arrays: bool = True, trace: bool = False,
            digests: bool = False, timeout: float | None = None,
            fields: FieldsArg = None) -> JobResult:
        """Runs an algorithm and returns its result.

        `algorithm`: "critical-points", "discrete-gradient", "morse-smale",
        "persistence-diagram", "topological-simplification", "merge-tree", "contour-tree",
        "topo-relations" ("morse_smale" works too), or over several fields "diagram-distance"
        (see distance_matrix()) or "tracking" (the pairs of consecutive fields matched into
        trajectories: the summary counts them, the ``tracking`` group holds TTK's tracking
        output).
        `parameters`: e.g. ``{"boundary_rule": "none"}``, ``{"embedding":
        "domain"}`` (persistence-diagram: its points at the vertices), ``{"relative_threshold":
        "0.05"}`` or ``{"persistence_threshold": "2.5"}`` (topological-simplification, and
        morse-smale, merge-tree and contour-tree on the simplified field), ``{"tree":
        "split"}`` (merge-tree: the split tree instead of the join tree), ``{"relations":
        "all"}`` (topo-relations: 22 relations instead of TTK's 20).
        `fields`: a list of point fields of the session's mesh, or "all" (every floating-point
        one, in the mesh's order), to run the algorithm over each of them in turn instead of
        over the session's scalar field;
        the result's ``fields`` then holds a FieldResult per field, each as a job on that
        field alone would give it (see run_fields() to get each as soon as it is done).
        `progress`: True for progress bars on stderr, one per phase ("faces": the mesh's edges
        and triangles, built by the first job or query on the mesh that reads them; then the
        run, over all the fields of a job over several; "distances" for diagram-distance's
        matrix), or a callable(fraction) of the run.
        `include_arrays`: False to receive only the summary and statistics.
        `trace`: True to record where the job's threads spent their time, as a Chrome trace
        (``result.trace``; ``result.save_trace("job.json")`` and open it in ui.perfetto.dev).
        `digests`: True to add the result's SHA-256 digests to the summary (its ``*_sha256``
        keys, comparable with TTK's); off by default, as they cost time on large meshes.
        Ctrl-C cancels the job on the server and raises KeyboardInterrupt.

        >>> result = session.run("critical-points")
        >>> result.summary["counts"]
        {'degenerate': 0, 'maximum': 1, 'minimum': 1, 'saddle1': 0, 'saddle2': 0}
        >>> result.critical_points["CriticalType"], result.critical_points["ttkVertexScalarField"]
        (array([0, 3], dtype=int8), array([0, 4], dtype=int32))
        """
        job: Job | None = None
        try:
            job = self.submit(algorithm, parameters=parameters, include_arrays=include_arrays,
                              trace=trace, digests=digests, timeout=timeout, fields=fields)
            return job.result(progress=progress)
        except KeyboardInterrupt:
            # Python raises Ctrl-C between any two steps: after submit() returned but before
            # `job` was set (the session's running job is then the one just started), or
            # before result() got to its own handler. The job is cancelled all the same.
            if job is None:
                self._cancel_unnamed_job()
            else:
                job._cancel_after_interrupt()
            raise

    def run_fields(self, algorithm: Algorithm, fields: FieldsArg, *,
                   parameters: Mapping[str, Any] | None = None, progress: ProgressArg = False,
                   include_arrays: bool = True, digests: bool = False,
                   timeout: float | None = None) -> Iterator[FieldResult]:
        """Runs an algorithm over several fields (names, or "all"), as run() does, and yields
        each field's FieldResult, in the job's order, as soon as the server has it; the
        results are not kept once yielded. The job starts when the iteration does. Closing
        the iterator before the end (``close()``, or leaving a ``with
        contextlib.closing(...)`` block), or Ctrl-C, cancels the job on the server.

        >>> mesh = client.upload_mesh((np.eye(4, 3), [[0, 1, 2, 3]], {"a": np.arange(4.0)}))
        >>> mesh = client.add_field(mesh, "b", [3.0, 2.0, 1.0, 0.0])
        >>> with client.open_session(mesh) as s:
        ...     for r in s.run_fields("critical-points", ["a", "b"]):
        ...         print(r.index, r.field, r.critical_points["ttkVertexScalarField"],
        ...               r.critical_points["CriticalType"])  # 0: minimum, 3: maximum
        0 a [0 3] [0 3]
        1 b [0 3] [3 0]
        >>> client.delete_mesh(mesh)
        """
        job = self._submit(algorithm, parameters, include_arrays, False, digests, timeout,
                           fields, keep_fields=False)
        bar = make_progress(progress, job.algorithm)
        try:
            yield from job._each_field(bar)
            job._assembler.result()  # the stream ended with its summary
        finally:
            job._call.cancel()  # a no-op once the job is over
            bar.close()

    def distance_matrix(self, fields: FieldsArg = "all", *, p: float = 2,
                        persistence_threshold: float | None = None,
                        relative_threshold: float | None = None, essential: bool = False,
                        progress: ProgressArg = False) -> DistanceMatrix:
        """The exact Wasserstein-p and bottleneck distances between the persistence diagrams
        of several fields of the session's mesh (at least two; "all": every floating-point
        one), from one diagram-distance job.

        `persistence_threshold` (absolute) or `relative_threshold` (a fraction of each field's
        own range) leaves out the pairs below it; `essential` matches the infinite pairs too
        (by birth; a distance between diagrams with different counts of them is then inf).
        `progress` as for run(): the diagrams' run, then the "distances" phase.
        """
        parameters = distance_parameters(p, persistence_threshold, relative_threshold,
                                         essential)
        result = self.run("diagram-distance", fields=fields, parameters=parameters,
                          include_arrays=False, progress=progress)
        return distance_matrix_of(result)

    def stats(self) -> SessionStats:
        """Cumulative statistics of the session (diff two snapshots for an interval)."""
        request = _messages.build_get_session_stats(self._id())
        response = self._client._call(self._client._stub.GetSessionStats, request)
        return _messages.decode_get_session_stats(response)


class _Feeder:
    """The sending side of a pipelined StreamRelations call. gRPC's sending thread iterates it;
    it holds that thread while `window` messages are unanswered, keeps what each message
    carries for the reader, and keeps an error of the caller's arrays for check() (an error
    raised in gRPC's thread would only cancel the call)."""

    def __init__(self, messages: Iterator[tuple[pb.StreamRelationsRequest, Piece]],
                 window: int) -> None:
        self._messages = messages
        self._window = window
        self._pieces: deque[Piece] = deque()
        self._changed = threading.Condition()
        self._closed = False
        self._error: Exception | None = None

    def __iter__(self) -> Iterator[pb.StreamRelationsRequest]:
        while True:
            with self._changed:
                self._changed.wait_for(
                    lambda: self._closed or len(self._pieces) < self._window)
                if self._closed:
                    return
            try:
                request, piece = next(self._messages)
            except StopIteration:
                return
            except Exception as e:
                self._error = e
                return
            with self._changed:
                self._pieces.append(piece)
            yield request

    def answered(self) -> Piece:
        """What the answer just read answers (answers come in order); frees a place."""
        with self._changed:
            if not self._pieces:
                raise ActopoError("StreamRelations: an answer to no request")
            piece = self._pieces.popleft()
            self._changed.notify_all()
        return piece

    def close(self) -> None:
        """Stops sending (wakes the sending thread if it waits)."""
        with self._changed:
            self._closed = True
            self._changed.notify_all()

    def check(self) -> None:
        """Raises the error that reading the caller's arrays raised, if any."""
        if self._error is not None:
            raise self._error


# How long Ctrl-C waits for the server to take a job's cancellation (Job.result()).
CANCEL_TIMEOUT_S = 5.0


class Job:
    """A running job (Session.submit()). ``job_id`` is known as soon as it is created;
    result() waits for the end; cancel() may be called from any thread."""

    def __init__(self, client: Client, call: ResponseStream[pb.RunJobResponse],
                 algorithm: Algorithm, keep_fields: bool = True) -> None:
        self._client = client
        self._call = call
        self._lock = threading.Lock()
        self._assembler = Assembler(algorithm, keep_fields)
        self.algorithm = algorithm
        self._interrupted = False
        self.job_id = ""
        try:
            with translated():
                for response in call:
                    self._assembler.feed(response)
                    if self._assembler.job_id:
                        break
            self.job_id = self._assembler.job_id
        except KeyboardInterrupt:
            self.job_id = self._assembler.job_id
            self._cancel_after_interrupt()
            raise

    def __repr__(self) -> str:
        return f"actopo.Job({self.job_id!r}, {self.algorithm!r})"

    def cancel(self) -> None:
        """Asks the server to cancel the job (CancelJob); result() then raises
        CancelledError."""
        self._client.cancel_job(self.job_id)

    def _cancel_after_interrupt(self) -> None:
        """Ctrl-C: CancelJob first, so that the job is cancelled on the server before
        KeyboardInterrupt reaches the caller (the stream's own cancellation reaches the server
        when its transport gets to it, which a busy server may take longer to notice than a
        short job takes to end), then the stream. A job that has ended, or a server that does
        not answer within CANCEL_TIMEOUT_S, leaves only the stream's cancellation. Once per
        job; before the server named the job, only the stream is cancelled."""
        if self._interrupted:
            return
        self._interrupted = True
        try:
            if self.job_id:
                self._client._stub.CancelJob(_messages.build_cancel_job(self.job_id),
                                             timeout=CANCEL_TIMEOUT_S,
                                             metadata=self._client._metadata)
        except grpc.RpcError:
            pass  # ended already, or unreachable: the stream's cancellation still goes
        finally:
            self._call.cancel()

    def result(self, progress: ProgressArg = False) -> JobResult:
        """Waits for the job and returns its result; Ctrl-C cancels it."""
        return self._result(progress)

    def _result(self, progress: ProgressArg,
                on_field: Callable[[FieldResult], Any] | None = None) -> JobResult:
        """result(), calling `on_field` with each field's result of a job over several as
        soon as it is complete (the CLI prints it then)."""
        with self._lock:
            bar = make_progress(progress, self.algorithm)
            try:
                for field in self._each_field(bar):
                    if on_field is not None:
                        on_field(field)
                return self._assembler.result()
            except KeyboardInterrupt:
                self._cancel_after_interrupt()
                raise
            finally:
                bar.close()

    def _each_field(self, bar: Progress[JobProgress]) -> Iterator[FieldResult]:
        """Reads the rest of the stream, reporting progress to `bar`; yields the result of
        each field of a job over several as soon as it is complete."""
        with translated():
            for response in self._call:
                report = self._assembler.feed(response)
                if report is not None:
                    bar.update(report)
                yield from self._assembler.take_fields()
