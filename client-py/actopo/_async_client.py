"""The asyncio client: AsyncClient, AsyncSession and AsyncJob, the same methods as coroutines."""

from __future__ import annotations

import asyncio
import contextlib
from collections import deque
from collections.abc import (
    AsyncIterator,
    Awaitable,
    Coroutine,
    Generator,
    Iterable,
    Iterator,
    Mapping,
    Sequence,
)
from typing import TYPE_CHECKING, Any

import grpc
import grpc.aio
import numpy as np

from actopo import _batches, _convert, _requests
from actopo._batches import Piece
from actopo._channel import (
    DEFAULT_TIMEOUT,
    MESH_TIMEOUT,
    TlsArg,
    async_channel,
    client_metadata,
    resolve_target,
)
from actopo._errors import ActopoError, error_for_number, translate, translated
from actopo._literals import Algorithm, Precompute, Prefetch, Relation, Structure
from actopo._mesh import MeshLike, mesh_arrays
from actopo._progress import (
    LoadProgressArg,
    Progress,
    ProgressArg,
    make_load_progress,
    make_progress,
)
from actopo._proto import pb, pb_grpc
from actopo._requests import MeshRef, SimplexArg
from actopo._results import Assembler, JobResult
from actopo._types import (
    LoadProgress,
    MeshInfo,
    RelationBatch,
    ServerInfo,
    SessionInfo,
    SessionStats,
    SimplexRelation,
    StreamItem,
)
from actopo._upload import requests as upload_requests

if TYPE_CHECKING:
    from typing_extensions import Self

_UNSET: Any = object()


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
        self._stub = pb_grpc.TopologyServiceStub(self._channel)
        self.affinity_key, self._metadata = client_metadata(token, affinity_key)
        self._timeout = timeout
        self._mesh_timeout = MESH_TIMEOUT if timeout is not None else None
        self._max_batch: int | None = None

    async def __aenter__(self) -> Self:
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    async def close(self) -> None:
        """Closes the channel."""
        await self._channel.close()

    def __repr__(self) -> str:
        return f"actopo.AsyncClient({self.target!r})"

    async def _call(self, method: str, request: Any, *, timeout: Any = _UNSET,
                    mesh: bool = False) -> Any:
        with translated(mesh=mesh):
            return await getattr(self._stub, method)(
                request, timeout=self._timeout if timeout is _UNSET else timeout,
                metadata=self._metadata)

    async def server_info(self) -> ServerInfo:
        """See Client.server_info()."""
        info = _convert.server_info(await self._call("GetServerInfo", pb.GetServerInfoRequest()))
        self._max_batch = info.limits.max_batch_size or _requests.DEFAULT_BATCH
        return info

    async def _batch_size(self) -> int:
        if self._max_batch is None:
            await self.server_info()
        return self._max_batch or _requests.DEFAULT_BATCH

    async def load_mesh(self, path: str, *, block_size: int = 0, block_label_field: str = "",
                        progress: LoadProgressArg = None) -> MeshInfo:
        """See Client.load_mesh(). Cancelling the awaiting task stops the load on the server."""
        request = _requests.load(path, block_size, block_label_field)
        if progress:
            return await self._load_reporting(request,
                                              make_load_progress(progress, f"load {path}"))
        response = await self._call("LoadMesh", request, timeout=self._mesh_timeout, mesh=True)
        return _convert.mesh_info(response.mesh)

    async def _load_reporting(self, request: pb.LoadMeshRequest,
                              bar: Progress[LoadProgress]) -> MeshInfo:
        """See Client._load_reporting()."""
        stream = _requests.LoadStream(bar.update)
        call = self._stub.LoadMeshWithProgress(pb.LoadMeshWithProgressRequest(load=request),
                                               timeout=self._mesh_timeout,
                                               metadata=self._metadata)
        try:
            with translated(mesh=True):
                while (response := await call.read()) is not grpc.aio.EOF:
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
                          block_label_field: str = "") -> MeshInfo:
        """See Client.upload_mesh()."""
        arrays = mesh_arrays(mesh, name)
        partition = _requests.partition(block_size, block_label_field)
        with translated(mesh=True):
            response = await self._stub.UploadMesh(upload_requests(arrays, partition),
                                                   timeout=self._mesh_timeout,
                                                   metadata=self._metadata)
        return _convert.mesh_info(response.mesh)

    async def list_meshes(self) -> list[MeshInfo]:
        """See Client.list_meshes()."""
        response = await self._call("ListMeshes", pb.ListMeshesRequest())
        return [_convert.mesh_info(m) for m in response.meshes]

    async def get_mesh(self, mesh: MeshRef) -> MeshInfo:
        """See Client.get_mesh()."""
        request = pb.GetMeshRequest(mesh_id=_requests.mesh_id(mesh))
        return _convert.mesh_info((await self._call("GetMesh", request)).mesh)

    async def delete_mesh(self, mesh: MeshRef) -> None:
        """See Client.delete_mesh()."""
        await self._call("DeleteMesh", pb.DeleteMeshRequest(mesh_id=_requests.mesh_id(mesh)))

    def open_session(self, mesh: MeshRef, *, scalar: str | None = None,
                     structure: Structure = "actopo", consumers: int = 0, producers: int = 0,
                     buffer_ratio: float = 0.0, prefetch: Prefetch = "auto",
                     precompute: Precompute = "auto", query_readers: int = 0) -> _SessionOpener:
        """See Client.open_session(). Await it, or use ``async with`` to close it at the end."""
        request = _requests.open_session(mesh, scalar, structure, consumers, producers,
                                         buffer_ratio, prefetch, precompute, query_readers)
        return _SessionOpener(self._open(request))

    async def _open(self, request: pb.OpenSessionRequest) -> AsyncSession:
        response = await self._call("OpenSession", request, timeout=self._mesh_timeout)
        return AsyncSession(self, _convert.session_info(response.session))

    async def session(self, session_id: str) -> AsyncSession:
        """See Client.session()."""
        return AsyncSession(self, await self.get_session(session_id))

    async def get_session(self, session_id: str) -> SessionInfo:
        """See Client.get_session()."""
        request = pb.GetSessionRequest(session_id=_requests.session_id(session_id))
        return _convert.session_info((await self._call("GetSession", request)).session)

    async def list_sessions(self) -> list[SessionInfo]:
        """See Client.list_sessions()."""
        response = await self._call("ListSessions", pb.ListSessionsRequest())
        return [_convert.session_info(s) for s in response.sessions]

    async def close_session(self, session_id: str) -> None:
        """See Client.close_session()."""
        request = pb.CloseSessionRequest(session_id=_requests.session_id(session_id))
        await self._call("CloseSession", request)

    async def cancel_job(self, job_id: str) -> None:
        """See Client.cancel_job()."""
        await self._call("CancelJob", pb.CancelJobRequest(job_id=job_id))


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

    async def relation(self, name: Relation, ids: Any, *,
                       raise_errors: bool = True) -> RelationBatch:
        """See Session.relation()."""
        values = _requests.simplex_array(ids)
        chunk = _batches.chunk_size(None, await self._client._batch_size())
        if raise_errors and len(values) <= chunk:
            request = pb.GetRelationBatchRequest(session_id=self._id(),
                                                 relation=_requests.relation(name),
                                                 **_requests.simplices(values))
            return _requests.merge([await self._client._call("GetRelationBatch", request)])
        batches = [b async for b in self.relation_batches(name, [values],
                                                          raise_errors=raise_errors)]
        return batches[0]

    async def relation_batches(self, name: Relation, arrays: Iterable[Any], *,
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
            while (response := await call.read()) is not grpc.aio.EOF:
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
        request = _requests.single(self._id(), name, simplex, include_vertices)
        return _requests.single_result(await self._client._call("GetRelation", request))

    async def relations_stream(self, name: Relation, simplices: Iterable[SimplexArg], *,
                               raise_errors: bool = False) -> AsyncIterator[StreamItem]:
        """See Session.relations_stream(); an async iterator."""
        call = self._client._stub.StreamRelations(
            _requests.stream(self._id(), name, simplices), metadata=self._client._metadata)
        try:
            while (response := await call.read()) is not grpc.aio.EOF:
                error = None
                if response.HasField("error") and response.error.code:
                    error = error_for_number(response.error.code, response.error.message)
                    if raise_errors:
                        raise error
                yield StreamItem(int(response.request_id),
                                 np.array(response.ids, dtype=np.int64), error)
        except grpc.RpcError as e:
            raise translate(e) from None
        finally:
            call.cancel()

    async def submit(self, algorithm: Algorithm, *, parameters: Mapping[str, Any] | None = None,
                     include_arrays: bool = True, trace: bool = False,
                     timeout: float | None = None) -> AsyncJob:
        """See Session.submit()."""
        request, name = _requests.run(self._id(), algorithm, parameters, include_arrays, trace)
        call = self._client._stub.RunJob(request, timeout=timeout,
                                         metadata=self._client._metadata)
        job = AsyncJob(self._client, call, name)
        await job._accepted()
        return job

    async def run(self, algorithm: Algorithm, *, parameters: Mapping[str, Any] | None = None,
                  progress: ProgressArg = False, include_arrays: bool = True,
                  trace: bool = False, timeout: float | None = None) -> JobResult:
        """See Session.run(). Cancelling the awaiting task cancels the job."""
        job = await self.submit(algorithm, parameters=parameters, include_arrays=include_arrays,
                                trace=trace, timeout=timeout)
        return await job.result(progress=progress)

    async def stats(self) -> SessionStats:
        """See Session.stats()."""
        request = pb.GetSessionStatsRequest(session_id=self._id())
        return _convert.session_stats(await self._client._call("GetSessionStats", request))


async def _write(call: Any, messages: Iterator[tuple[pb.StreamRelationsRequest, Piece]],
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

    def __init__(self, client: AsyncClient, call: Any, algorithm: Algorithm) -> None:
        self._client = client
        self._call = call
        self._assembler = Assembler(algorithm)
        self.algorithm = algorithm
        self.job_id = ""

    def __repr__(self) -> str:
        return f"actopo.AsyncJob({self.job_id!r}, {self.algorithm!r})"

    async def _read(self, on_progress: Any = None) -> bool:
        """Reads one response; False at the end of the stream."""
        response = await self._call.read()
        if response is grpc.aio.EOF:
            return False
        fraction = self._assembler.feed(response)
        if fraction is not None and on_progress is not None:
            on_progress(fraction)
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
            with translated():
                while await self._read(bar.update):
                    pass
            return self._assembler.result()
        except (asyncio.CancelledError, KeyboardInterrupt):
            self._call.cancel()
            raise
        finally:
            bar.close()
