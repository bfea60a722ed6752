"""The asyncio client: AsyncClient, AsyncSession and AsyncJob, the same methods as coroutines."""

from __future__ import annotations

import asyncio
import contextlib
import os
from collections import deque
from collections.abc import (
    AsyncIterator,
    Awaitable,
    Callable,
    Coroutine,
    Generator,
    Iterable,
    Iterator,
    Mapping,
    Sequence,
)
from typing import TYPE_CHECKING, Any, TypeVar

import grpc
import grpc.aio
import numpy as np
import numpy.typing as npt

from actopo import _batches, _file_upload, _messages, _requests
from actopo._batches import Piece
from actopo._channel import (
    DEFAULT_TIMEOUT,
    MESH_TIMEOUT,
    OWN_CONNECTION,
    TlsArg,
    async_channel,
    client_metadata,
    resolve_target,
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
from actopo._stub import async_stub
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


class AsyncClient:
    """The asyncio twin of Client: same arguments, same methods, as coroutines.

    Create it inside the event loop that uses it. Cancelling the task that awaits a job or a
    load (or Ctrl-C under asyncio.run) cancels it on the server.

    Example::

        import asyncio, actopo

        async def main():
            async with actopo.AsyncClient("127.0.0.1:50051") as client:
                mesh = await client.sample("jittered:32")
                async with client.open_session(mesh, structure="actopo") as session:
                    result = await session.run("critical-points")
                    print(result.summary["counts"])

        asyncio.run(main())
    """

    def __init__(self, target: str | None = None, *, token: str | None = None,
                 affinity_key: str | None = None,
                 tls: TlsArg = False, timeout: float | None = DEFAULT_TIMEOUT,
                 options: Sequence[tuple[str, Any]] = (), retries: bool = True) -> None:
        self.target = resolve_target(target)
        self._channel = async_channel(self.target, tls, options, retries)
        self._stub = async_stub(self._channel)
        self.affinity_key, self._metadata = client_metadata(token, affinity_key)
        self._timeout = timeout
        self._mesh_timeout = MESH_TIMEOUT if timeout is not None else None
        self._max_batch: int | None = None
        self._retries = retries
        self._channel_args = (tls, tuple(options))

    async def __aenter__(self) -> Self:
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    async def close(self) -> None:
        """Closes the channel."""
        await self._channel.close()

    def __repr__(self) -> str:
        return f"actopo.AsyncClient({self.target!r})"

    async def _call(self, rpc: grpc.aio.UnaryUnaryMultiCallable[_Request, _Response],
                    request: _Request, *, long: bool = False, mesh: bool = False) -> _Response:
        """See Client._call()."""
        with translated(mesh=mesh):
            return await rpc(request, timeout=self._mesh_timeout if long else self._timeout,
                             metadata=self._metadata)

    async def server_info(self) -> ServerInfo:
        """See Client.server_info()."""
        response = await self._call(self._stub.GetServerInfo, _messages.build_get_server_info())
        info = _messages.decode_get_server_info(response)
        self._max_batch = _messages.max_batch(info)
        return info

    async def _batch_size(self) -> int:
        if self._max_batch is None:
            await self.server_info()
        return self._max_batch or _requests.DEFAULT_BATCH

    async def load_mesh(self, path: MeshSource, *, times: Sequence[float] | None = None,
                        block_size: int = 0, block_label_field: str = "",
                        progress: LoadProgressArg = None) -> MeshInfo:
        """See Client.load_mesh() (a path, or a list of a series' files with `times`).
        Cancelling the awaiting task stops the load on the server."""
        request = _messages.build_load_mesh(path, block_size, block_label_field, times)
        if progress:
            return await self._load_reporting(
                request, make_load_progress(progress, _messages.load_description(request)))
        response = await self._call(self._stub.LoadMesh, request, long=True, mesh=True)
        return _messages.decode_load_mesh(response)

    async def _load_reporting(self, request: pb.LoadMeshRequest,
                              bar: Progress[LoadProgress]) -> MeshInfo:
        """See Client._load_reporting()."""
        stream = _messages.LoadStream(bar.update)
        call = self._stub.LoadMeshWithProgress(_messages.build_load_mesh_with_progress(request),
                                               timeout=self._mesh_timeout,
                                               metadata=self._metadata)
        try:
            with translated(mesh=True):
                async for response in call:
                    stream.feed(response)
        finally:
            call.cancel()  # stops the load after cancellation or a raising callback
            bar.close()
        return stream.mesh()

    async def sample(self, name: str, *, block_size: int = 0,
                     progress: LoadProgressArg = None) -> MeshInfo:
        """See Client.sample()."""
        return await self.load_mesh(f"sample:{name}", block_size=block_size, progress=progress)

    async def upload_mesh(self, mesh: MeshLike, *, name: str | None = None, block_size: int = 0,
                          block_label_field: str = "",
                          compression: grpc.Compression | None = None) -> MeshInfo:
        """See Client.upload_mesh() (a .vtu, .vtk, .vti or .pvd file goes as upload_file()
        sends it)."""
        if isinstance(mesh, (str, os.PathLike)) and _file_upload.is_mesh_file(mesh):
            try:
                return await self.upload_file(mesh, name=name, block_size=block_size,
                                              block_label_field=block_label_field)
            except ActopoError as e:  # a server from before file uploads: the arrays, as then
                if e.code != grpc.StatusCode.UNIMPLEMENTED:
                    raise
        requests = _messages.build_upload_mesh(mesh, name, block_size, block_label_field)
        with translated(mesh=True):
            response = await self._stub.UploadMesh(requests, timeout=self._mesh_timeout,
                                                   metadata=self._metadata,
                                                   compression=compression)
        return _messages.decode_upload_mesh(response)

    async def upload_file(self, path: str | os.PathLike[str], *, name: str | None = None,
                          block_size: int = 0, block_label_field: str = "",
                          progress: LoadProgressArg = None) -> MeshInfo:
        """See Client.upload_file(). The files are hashed and read in a thread, so the event
        loop goes on meanwhile; cancelling the awaiting task deletes the upload (or stops its
        load) on the server."""
        options = partition(block_size, block_label_field)
        files = await asyncio.to_thread(_file_upload.upload_plan, path, name)
        bar = make_load_progress(progress, _file_upload.description(files), UPLOAD_PHASES)
        try:
            upload_id = await self._send_files(files, bar)
        except BaseException:
            bar.close()
            raise
        try:
            return await self._load_reporting(
                _file_upload.build_load_upload(upload_id, options), bar)
        except BaseException:
            await self._delete_upload(upload_id)  # see Client.upload_file()
            raise

    async def _send_files(self, files: list[LocalFile], bar: Progress[LoadProgress]) -> str:
        """See Client._send_files()."""
        created = await self._call(self._stub.CreateUpload, _file_upload.create_request(files),
                                   long=True)
        try:
            await self._send(Sender(files, self._retries), created.upload, bar)
        except BaseException:
            await self._delete_upload(created.upload.upload_id, own_connection=True)
            raise
        return created.upload.upload_id

    async def _send(self, sender: Sender, status: pb.UploadStatus,
                    bar: Progress[LoadProgress]) -> None:
        """See Client._send()."""
        upload_id = status.upload_id
        where = sender.next_write(status)
        sender.report(bar)
        while where is not None:
            try:
                status = await self._write_upload(sender, upload_id, *where, bar)
                where = sender.next_write(status, wrote=True)
            except grpc.RpcError as e:
                where = sender.next_write(await self._resume(sender, upload_id, e))
        sender.report(bar)

    async def _write_upload(self, sender: Sender, upload_id: str, file: int, offset: int,
                            bar: Progress[LoadProgress]) -> pb.UploadStatus:
        """One WriteUpload call, its messages written one at a time (each chunk read from the
        file in a thread), the bytes sent reported after each."""
        call = self._stub.WriteUpload(timeout=self._mesh_timeout, metadata=self._metadata)
        requests = sender.requests(upload_id, file, offset)
        try:
            try:
                while (request := await asyncio.to_thread(next, requests, None)) is not None:
                    await call.write(request)
                    sender.report(bar)
                await call.done_writing()
            except asyncio.InvalidStateError:
                pass  # the call is over: awaiting it raises its status
            response = await call
        except grpc.RpcError:
            raise
        except BaseException:
            call.cancel()  # after cancellation or a raising callback
            raise
        sender.check()
        sender.report(bar)
        return response.upload

    async def _resume(self, sender: Sender, upload_id: str,
                      error: grpc.RpcError) -> pb.UploadStatus:
        """See Client._resume()."""
        while True:
            await asyncio.sleep(sender.failed(error))
            try:
                response = await self._stub.GetUpload(pb.GetUploadRequest(upload_id=upload_id),
                                                      timeout=self._timeout,
                                                      metadata=self._metadata)
                return response.upload
            except grpc.RpcError as e:
                error = e

    async def _delete_upload(self, upload_id: str, *, own_connection: bool = False) -> None:
        """See Client._delete_upload()."""
        request = pb.DeleteUploadRequest(upload_id=upload_id)
        async with contextlib.AsyncExitStack() as stack:
            stub = self._stub
            if own_connection:
                tls, options = self._channel_args
                stub = async_stub(await stack.enter_async_context(async_channel(
                    self.target, tls, [*options, OWN_CONNECTION], self._retries)))
            with contextlib.suppress(grpc.RpcError):
                await stub.DeleteUpload(request, timeout=_file_upload.DELETE_SECONDS,
                                        metadata=self._metadata, wait_for_ready=True)

    async def download_mesh(self, mesh: MeshRef, fields: FieldsArg = None, *,
                            progress: ProgressArg = None) -> MeshArrays:
        """See Client.download_mesh(). Cancelling the awaiting task stops the download."""
        request = _messages.build_download_mesh(mesh, fields)
        bar = make_fraction_progress(progress, _messages.download_description(mesh))
        stream = MeshStream(bar.update)
        call = self._stub.DownloadMesh(request, timeout=self._mesh_timeout,
                                       metadata=self._metadata)
        try:
            with translated():
                async for response in call:
                    stream.feed(response)
        finally:
            call.cancel()  # stops the download after cancellation or a raising callback
            bar.close()
        return stream.mesh()

    async def list_meshes(self) -> list[MeshInfo]:
        """See Client.list_meshes()."""
        response = await self._call(self._stub.ListMeshes, _messages.build_list_meshes())
        return _messages.decode_list_meshes(response)

    async def get_mesh(self, mesh: MeshRef, *, count_faces: bool = False) -> MeshInfo:
        """See Client.get_mesh()."""
        response = await self._call(self._stub.GetMesh,
                                    _messages.build_get_mesh(mesh, count_faces),
                                    long=count_faces)
        return _messages.decode_get_mesh(response)

    async def delete_mesh(self, mesh: MeshRef) -> None:
        """See Client.delete_mesh()."""
        await self._call(self._stub.DeleteMesh, _messages.build_delete_mesh(mesh))

    async def add_fields(self, mesh: MeshRef, fields: FieldsLike, *,
                         times: TimesArg = None) -> MeshInfo:
        """See Client.add_fields()."""
        vertices = mesh.vertices if isinstance(mesh, MeshInfo) \
            else (await self.get_mesh(mesh)).vertices
        requests = _messages.build_add_fields(mesh, fields, vertices, times)
        with translated():
            response = await self._stub.AddFields(requests, timeout=self._mesh_timeout,
                                                  metadata=self._metadata)
        return _messages.decode_add_fields(response)

    async def add_field(self, mesh: MeshRef, name: str, values: npt.ArrayLike, *,
                        time: float | None = None) -> MeshInfo:
        """See Client.add_field()."""
        return await self.add_fields(mesh, {name: values},
                                     times=None if time is None else [time])

    async def delete_field(self, mesh: MeshRef, name: str) -> MeshInfo:
        """See Client.delete_field()."""
        response = await self._call(self._stub.DeleteField,
                                    _messages.build_delete_field(mesh, name))
        return _messages.decode_delete_field(response)

    def open_session(self, mesh: MeshRef, *, scalar: str | None = None,
                     structure: Structure = "actopo", consumers: int = 0, producers: int = 0,
                     buffer_ratio: float = 0.0, prefetch: Prefetch = "auto",
                     precompute: Precompute = "auto", query_readers: int = 0) -> _SessionOpener:
        """See Client.open_session(). Await it, or use ``async with`` to close it at the end."""
        request = _messages.build_open_session(mesh, scalar, structure, consumers, producers,
                                               buffer_ratio, prefetch, precompute, query_readers)
        return _SessionOpener(self._open(request))

    async def _open(self, request: pb.OpenSessionRequest) -> AsyncSession:
        response = await self._call(self._stub.OpenSession, request, long=True)
        return AsyncSession(self, _messages.decode_open_session(response))

    async def session(self, session_id: str) -> AsyncSession:
        """See Client.session()."""
        return AsyncSession(self, await self.get_session(session_id))

    async def get_session(self, session_id: str) -> SessionInfo:
        """See Client.get_session()."""
        response = await self._call(self._stub.GetSession,
                                    _messages.build_get_session(session_id))
        return _messages.decode_get_session(response)

    async def list_sessions(self) -> list[SessionInfo]:
        """See Client.list_sessions()."""
        response = await self._call(self._stub.ListSessions, _messages.build_list_sessions())
        return _messages.decode_list_sessions(response)

    async def close_session(self, session_id: str) -> None:
        """See Client.close_session()."""
        await self._call(self._stub.CloseSession, _messages.build_close_session(session_id))

    async def cancel_job(self, job_id: str) -> None:
        """See Client.cancel_job()."""
        await self._call(self._stub.CancelJob, _messages.build_cancel_job(job_id))


class _SessionOpener(Awaitable["AsyncSession"]):
    """What AsyncClient.open_session() returns: awaitable, or an async context manager."""

    def __init__(self, opening: Coroutine[Any, Any, AsyncSession]) -> None:
        self._opening = opening
        self._session: AsyncSession | None = None

    def __await__(self) -> Generator[Any, None, AsyncSession]:
        return self._opening.__await__()

    async def __aenter__(self) -> AsyncSession:
        self._session = await self._opening
        return self._session

    async def __aexit__(self, *exc: object) -> None:
        if self._session is not None:
            await self._session.close()


class AsyncSession:
    """The asyncio twin of Session."""

    def __init__(self, client: AsyncClient, info: SessionInfo) -> None:
        self._client = client
        self.info = info
        self.session_id = info.session_id

    async def __aenter__(self) -> Self:
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    def __repr__(self) -> str:
        return (f"actopo.AsyncSession({self.session_id!r}, mesh={self.info.mesh_id!r}, "
                f"structure={self.info.structure!r})")

    def _id(self) -> str:
        if not self.session_id:
            raise ValueError("the session is closed")
        return self.session_id

    async def close(self) -> None:
        """See Session.close()."""
        if self.session_id:
            session_id, self.session_id = self.session_id, ""
            await self._client.close_session(session_id)

    async def describe(self) -> SessionInfo:
        """See Session.describe()."""
        self.info = await self._client.get_session(self._id())
        return self.info

    async def relation(self, name: Relation, ids: SimplexIds, *,
                       raise_errors: bool = True) -> RelationBatch:
        """See Session.relation()."""
        values = _requests.simplex_array(ids)
        if _batches.in_one_call(values, raise_errors, await self._client._batch_size()):
            return await self._batch(_requests.relation(name), values)
        [batch] = [b async for b in self.relation_batches(name, [values],
                                                          raise_errors=raise_errors)]
        return batch

    async def _batch(self, code: pb.Relation, values: np.ndarray) -> RelationBatch:
        """See Session._batch()."""
        request = _messages.build_get_relation_batch(self._id(), code, values)
        response = await self._client._call(self._client._stub.GetRelationBatch, request)
        return _messages.decode_get_relation_batch(response)

    async def relation_batches(self, name: Relation, arrays: Iterable[SimplexIds], *,
                               chunk_size: int | None = None,
                               window: int = _batches.STREAM_WINDOW,
                               raise_errors: bool = False) -> AsyncIterator[RelationBatch]:
        """See Session.relation_batches(); an async iterator. `arrays` is a plain iterable,
        read by a task that writes the messages while this one reads the answers."""
        chunk = _batches.chunk_size(chunk_size, await self._client._batch_size())
        messages = _batches.messages(self._id(), _requests.relation(name), arrays, chunk)
        slots = asyncio.Semaphore(_batches.window_size(window))
        pieces: deque[Piece] = deque()
        failed: list[Exception] = []
        collector = _batches.Collector(raise_errors)
        call = self._client._stub.StreamRelations(metadata=self._client._metadata)
        writer = asyncio.ensure_future(_write(call, messages, slots, pieces, failed))
        try:
            async for response in call:
                if not pieces:
                    raise ActopoError("StreamRelations: an answer to no request")
                slots.release()
                batch = collector.add(pieces.popleft(), response)
                if batch is not None:
                    yield batch
        except grpc.RpcError as e:
            if failed:
                raise failed[0] from None
            raise translate(e) from None
        finally:
            writer.cancel()
            call.cancel()
        if failed:
            raise failed[0]

    async def query(self, name: Relation, simplex: SimplexArg, *,
                    include_vertices: bool = False) -> SimplexRelation:
        """See Session.query()."""
        request = _messages.build_get_relation(self._id(), name, simplex, include_vertices)
        response = await self._client._call(self._client._stub.GetRelation, request)
        return _messages.decode_get_relation(response)

    async def relations_stream(self, name: Relation, simplices: Iterable[SimplexArg], *,
                               raise_errors: bool = False) -> AsyncIterator[StreamItem]:
        """See Session.relations_stream(); an async iterator."""
        call = self._client._stub.StreamRelations(
            _messages.build_stream_relations(self._id(), name, simplices),
            metadata=self._client._metadata)
        try:
            async for response in call:
                yield _messages.decode_stream_relations(response, raise_errors)
        except grpc.RpcError as e:
            raise translate(e) from None
        finally:
            call.cancel()

    async def submit(self, algorithm: Algorithm, *, parameters: Mapping[str, Any] | None = None,
                     include_arrays: bool = True, trace: bool = False, digests: bool = False,
                     timeout: float | None = None, fields: FieldsArg = None) -> AsyncJob:
        """See Session.submit()."""
        return await self._submit(algorithm, parameters, include_arrays, trace, digests,
                                  timeout, fields)

    async def _submit(self, algorithm: Algorithm, parameters: Mapping[str, Any] | None,
                      include_arrays: bool, trace: bool, digests: bool, timeout: float | None,
                      fields: FieldsArg, keep_fields: bool = True) -> AsyncJob:
        request, name = _messages.build_run_job(self._id(), algorithm, parameters,
                                                include_arrays, trace, digests, fields)
        call = self._client._stub.RunJob(request, timeout=timeout,
                                         metadata=self._client._metadata)
        job = AsyncJob(self._client, call, name, keep_fields)
        await job._accepted()
        return job

    async def run(self, algorithm: Algorithm, *, parameters: Mapping[str, Any] | None = None,
                  progress: ProgressArg = False, include_arrays: bool = True,
                  trace: bool = False, digests: bool = False,
                  timeout: float | None = None, fields: FieldsArg = None) -> JobResult:
        """See Session.run(). Cancelling the awaiting task cancels the job."""
        job = await self.submit(algorithm, parameters=parameters, include_arrays=include_arrays,
                                trace=trace, digests=digests, timeout=timeout, fields=fields)
        return await job.result(progress=progress)

    async def run_fields(self, algorithm: Algorithm, fields: FieldsArg, *,
                         parameters: Mapping[str, Any] | None = None,
                         progress: ProgressArg = False, include_arrays: bool = True,
                         digests: bool = False,
                         timeout: float | None = None) -> AsyncIterator[FieldResult]:
        """See Session.run_fields(); an async iterator. Closing it early (``aclose()``, or
        leaving a ``contextlib.aclosing(...)`` block), or cancelling the task that iterates
        it, cancels the job."""
        job = await self._submit(algorithm, parameters, include_arrays, False, digests, timeout,
                                 fields, keep_fields=False)
        bar = make_progress(progress, job.algorithm)
        try:
            async for result in job._each_field(bar):
                yield result
            job._assembler.result()  # the stream ended with its summary
        finally:
            job._call.cancel()  # a no-op once the job is over
            bar.close()

    async def distance_matrix(self, fields: FieldsArg = "all", *, p: float = 2,
                              persistence_threshold: float | None = None,
                              relative_threshold: float | None = None, essential: bool = False,
                              progress: ProgressArg = False) -> DistanceMatrix:
        """See Session.distance_matrix()."""
        parameters = distance_parameters(p, persistence_threshold, relative_threshold,
                                         essential)
        result = await self.run("diagram-distance", fields=fields, parameters=parameters,
                                include_arrays=False, progress=progress)
        return distance_matrix_of(result)

    async def stats(self) -> SessionStats:
        """See Session.stats()."""
        request = _messages.build_get_session_stats(self._id())
        response = await self._client._call(self._client._stub.GetSessionStats, request)
        return _messages.decode_get_session_stats(response)


async def _write(call: grpc.aio.StreamStreamCall[pb.StreamRelationsRequest,
                                                 pb.StreamRelationsResponse],
                 messages: Iterator[tuple[pb.StreamRelationsRequest, Piece]],
                 slots: asyncio.Semaphore, pieces: deque[Piece], failed: list[Exception]) -> None:
    """The sending side of AsyncSession.relation_batches(): writes the messages, each once a
    place in the window is free, noting what each carries; an error of the caller's arrays
    goes to `failed` and ends the sending (the reader raises it)."""
    while True:
        try:
            request, piece = next(messages)
        except StopIteration:
            break
        except Exception as e:
            failed.append(e)
            break
        await slots.acquire()
        pieces.append(piece)
        try:
            await call.write(request)
        except (grpc.RpcError, asyncio.InvalidStateError):
            return  # the call ended: the reader sees why
    with contextlib.suppress(grpc.RpcError, asyncio.InvalidStateError):
        await call.done_writing()


class AsyncJob:
    """The asyncio twin of Job."""

    def __init__(self, client: AsyncClient,
                 call: grpc.aio.UnaryStreamCall[pb.RunJobRequest, pb.RunJobResponse],
                 algorithm: Algorithm, keep_fields: bool = True) -> None:
        self._client = client
        self._call = call
        self._responses = aiter(call)
        self._assembler = Assembler(algorithm, keep_fields)
        self.algorithm = algorithm
        self.job_id = ""

    def __repr__(self) -> str:
        return f"actopo.AsyncJob({self.job_id!r}, {self.algorithm!r})"

    async def _read(self, on_progress: Callable[[JobProgress], Any] | None = None) -> bool:
        """Reads one response; False at the end of the stream."""
        response = await anext(self._responses, None)
        if response is None:
            return False
        report = self._assembler.feed(response)
        if report is not None and on_progress is not None:
            on_progress(report)
        return True

    async def _accepted(self) -> None:
        try:
            with translated():
                while not self._assembler.job_id and await self._read():
                    pass
        except (asyncio.CancelledError, KeyboardInterrupt):
            self._call.cancel()
            raise
        self.job_id = self._assembler.job_id

    async def cancel(self) -> None:
        """See Job.cancel()."""
        await self._client.cancel_job(self.job_id)

    async def result(self, progress: ProgressArg = False) -> JobResult:
        """See Job.result()."""
        bar = make_progress(progress, self.algorithm)
        try:
            async for _ in self._each_field(bar):
                pass
            return self._assembler.result()
        except (asyncio.CancelledError, KeyboardInterrupt):
            self._call.cancel()
            raise
        finally:
            bar.close()

    async def _each_field(self, bar: Progress[JobProgress]) -> AsyncIterator[FieldResult]:
        """See Job._each_field()."""
        with translated():
            while await self._read(bar.update):
                for result in self._assembler.take_fields():
                    yield result
