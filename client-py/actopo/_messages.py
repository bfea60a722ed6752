"""What each RPC sends and what its answer means: build_<rpc>() makes the request of an RPC of
actopo.v1.TopologyService from the caller's arguments, decode_<rpc>() turns its response into
the package's types. Pure functions, no calls: Client and AsyncClient both use them, and differ
only in how they make the call, blocking or awaited::

    return _messages.decode_get_mesh(self._call(stub.GetMesh, _messages.build_get_mesh(mesh)))

Streamed responses are decoded one message at a time: LoadStream (LoadMeshWithProgress),
_download.MeshStream (DownloadMesh), decode_stream_relations() (StreamRelations, one simplex a
message), _batches.Collector (StreamRelations, arrays of simplices) and _results.Assembler
(RunJob).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from typing import Any, cast

import numpy as np

from actopo import _convert, _names, _upload
from actopo._arrays import to_numpy
from actopo._errors import ActopoError, InvalidArgumentError, error_for_number
from actopo._fields import FieldsLike, TimesArg, field_arrays
from actopo._literals import Algorithm, Precompute, Prefetch, Relation, Structure
from actopo._mesh import MeshLike, mesh_arrays
from actopo._proto import pb
from actopo._requests import (
    DEFAULT_BATCH,
    FieldsArg,
    MeshRef,
    MeshSource,
    SessionRef,
    SimplexArg,
    download_fields,
    engine_count,
    file_series,
    job_fields,
    mesh_id,
    partition,
    relation,
    session_id,
    simplex,
    simplices,
)
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

# Server.


def build_get_server_info() -> pb.GetServerInfoRequest:
    return pb.GetServerInfoRequest()


def decode_get_server_info(response: pb.GetServerInfoResponse) -> ServerInfo:
    return _convert.server_info(response)


def max_batch(info: ServerInfo) -> int:
    """Simplices one GetRelationBatch call may carry on this server."""
    return info.limits.max_batch_size or DEFAULT_BATCH


# Meshes.


def build_load_mesh(source: MeshSource, block_size: int = 0, block_label_field: str = "",
                    times: Sequence[float] | None = None) -> pb.LoadMeshRequest:
    """`source`: a path under the server's data directory, "sample:NAME", or a list of paths,
    the files of a series (`times`: one per file; None: the files' indices)."""
    options = partition(block_size, block_label_field)
    if not isinstance(source, str):
        return pb.LoadMeshRequest(files=file_series(source, times), partition=options)
    if times is not None:
        raise InvalidArgumentError("times: only with a list of paths (the files of a "
                                   "series); a .pvd gives its own")
    if source.startswith("sample:"):
        return pb.LoadMeshRequest(sample=source[len("sample:"):], partition=options)
    return pb.LoadMeshRequest(path=source, partition=options)


def load_description(request: pb.LoadMeshRequest) -> str:
    """What the progress bars of a load say: "load PATH", "load sample:NAME", or a series' first
    file and how many more ("load a.vtu +3 files", as the server names the mesh)."""
    which = request.WhichOneof("source")
    if which == "sample":
        return f"load sample:{request.sample}"
    if which != "files":
        return f"load {request.path}"
    paths = request.files.paths
    others = len(paths) - 1
    more = f" +{others} file{'s' if others > 1 else ''}" if others > 0 else ""
    return f"load {paths[0] if paths else 'no files'}{more}"


def decode_load_mesh(response: pb.LoadMeshResponse) -> MeshInfo:
    return _convert.mesh_info(response.mesh)


def build_load_mesh_with_progress(load: pb.LoadMeshRequest) -> pb.LoadMeshWithProgressRequest:
    """`load`: build_load_mesh()'s request."""
    return pb.LoadMeshWithProgressRequest(load=load)


class LoadStream:
    """Decodes the answers of LoadMeshWithProgress: each progress message goes to `report`
    (which may raise, to stop the load), the mesh, which ends the stream, is kept for mesh()."""

    def __init__(self, report: Callable[[LoadProgress], Any]) -> None:
        self._report = report
        self._mesh: MeshInfo | None = None

    def feed(self, response: pb.LoadMeshWithProgressResponse) -> None:
        event = response.WhichOneof("event")
        if event == "progress":
            self._report(_convert.load_progress(response.progress))
        elif event == "mesh":
            self._mesh = _convert.mesh_info(response.mesh)

    def mesh(self) -> MeshInfo:
        if self._mesh is None:
            raise ActopoError("LoadMeshWithProgress: the stream ended without the mesh")
        return self._mesh


def build_upload_mesh(mesh: MeshLike, name: str | None, block_size: int = 0,
                      block_label_field: str = "") -> Iterator[pb.UploadMeshRequest]:
    """The messages of an upload. The mesh is read and checked here, in the caller's thread
    (see _upload.requests)."""
    return _upload.requests(mesh_arrays(mesh, name), partition(block_size, block_label_field))


def decode_upload_mesh(response: pb.UploadMeshResponse) -> MeshInfo:
    return _convert.mesh_info(response.mesh)


def build_download_mesh(mesh: MeshRef, fields: FieldsArg) -> pb.DownloadMeshRequest:
    """`fields`: names, "all", or None for the points and tetrahedra alone."""
    return pb.DownloadMeshRequest(mesh_id=mesh_id(mesh), **download_fields(fields))


def download_description(mesh: MeshRef) -> str:
    """What the progress bar of a download says: "download NAME" (the id for a mesh given by
    id)."""
    return f"download {mesh.name if isinstance(mesh, MeshInfo) else mesh}"


def build_list_meshes() -> pb.ListMeshesRequest:
    return pb.ListMeshesRequest()


def decode_list_meshes(response: pb.ListMeshesResponse) -> list[MeshInfo]:
    return [_convert.mesh_info(m) for m in response.meshes]


def build_get_mesh(mesh: MeshRef, count_faces: bool = False) -> pb.GetMeshRequest:
    return pb.GetMeshRequest(mesh_id=mesh_id(mesh), count_faces=count_faces)


def decode_get_mesh(response: pb.GetMeshResponse) -> MeshInfo:
    return _convert.mesh_info(response.mesh)


def build_delete_mesh(mesh: MeshRef) -> pb.DeleteMeshRequest:
    return pb.DeleteMeshRequest(mesh_id=mesh_id(mesh))


def build_add_fields(mesh: MeshRef, fields: FieldsLike, vertices: int,
                     times: TimesArg = None) -> Iterator[pb.AddFieldsRequest]:
    """The messages of AddFields. The fields are checked here against the mesh's `vertices`,
    in the caller's thread and before anything is sent (see _fields)."""
    return _upload.add_fields_requests(mesh_id(mesh), field_arrays(fields, vertices, times))


def decode_add_fields(response: pb.AddFieldsResponse) -> MeshInfo:
    return _convert.mesh_info(response.mesh)


def build_delete_field(mesh: MeshRef, name: str) -> pb.DeleteFieldRequest:
    return pb.DeleteFieldRequest(mesh_id=mesh_id(mesh), name=name)


def decode_delete_field(response: pb.DeleteFieldResponse) -> MeshInfo:
    return _convert.mesh_info(response.mesh)


# Sessions.


def build_open_session(mesh: MeshRef, scalar: str | None, structure: Structure, consumers: int,
                       producers: int, buffer_ratio: float, prefetch: Prefetch,
                       precompute: Precompute, query_readers: int = 0) -> pb.OpenSessionRequest:
    engine = pb.EngineOptions(consumers=engine_count("consumers", consumers),
                              producers=engine_count("producers", producers),
                              buffer_ratio=buffer_ratio,
                              prefetch=_names.lookup(_names.PREFETCH, prefetch, "prefetch"),
                              precompute=_names.lookup(_names.PRECOMPUTE, precompute,
                                                       "precompute"),
                              query_readers=engine_count("query_readers", query_readers))
    return pb.OpenSessionRequest(
        mesh_id=mesh_id(mesh), scalar_field=scalar or "",
        structure=_names.lookup(_names.STRUCTURES, structure, "structure"), engine=engine)


def decode_open_session(response: pb.OpenSessionResponse) -> SessionInfo:
    return _convert.session_info(response.session)


def build_get_session(session: SessionRef) -> pb.GetSessionRequest:
    return pb.GetSessionRequest(session_id=session_id(session))


def decode_get_session(response: pb.GetSessionResponse) -> SessionInfo:
    return _convert.session_info(response.session)


def build_list_sessions() -> pb.ListSessionsRequest:
    return pb.ListSessionsRequest()


def decode_list_sessions(response: pb.ListSessionsResponse) -> list[SessionInfo]:
    return [_convert.session_info(s) for s in response.sessions]


def build_close_session(session: SessionRef) -> pb.CloseSessionRequest:
    return pb.CloseSessionRequest(session_id=session_id(session))


def build_get_session_stats(session: SessionRef) -> pb.GetSessionStatsRequest:
    return pb.GetSessionStatsRequest(session_id=session_id(session))


def decode_get_session_stats(response: pb.GetSessionStatsResponse) -> SessionStats:
    return _convert.session_stats(response)


# Relations.


def build_get_relation(session: SessionRef, name: Relation, value: SimplexArg,
                       include_vertices: bool) -> pb.GetRelationRequest:
    return pb.GetRelationRequest(session_id=session_id(session), relation=relation(name),
                                 simplex=simplex(value), include_vertices=include_vertices)


def decode_get_relation(response: pb.GetRelationResponse) -> SimplexRelation:
    ids = np.array(response.ids, dtype=np.int64)
    vertices = None
    if len(response.vertices):
        vertices = np.array(response.vertices, dtype=np.int64).reshape(len(ids), -1)
    return SimplexRelation(ids, vertices)


def build_get_relation_batch(session: SessionRef, code: pb.Relation,
                             values: np.ndarray) -> pb.GetRelationBatchRequest:
    """`code`: relation()'s; `values`: _requests.simplex_array()'s ids or vertex tuples."""
    return pb.GetRelationBatchRequest(session_id=session_id(session), relation=code,
                                      **simplices(values))


def decode_get_relation_batch(response: pb.GetRelationBatchResponse) -> RelationBatch:
    return RelationBatch(to_numpy(response.offsets).astype(np.int64, copy=False),
                         to_numpy(response.values).astype(np.int64, copy=False))


def build_stream_relations(session: SessionRef, name: Relation,
                           values: Iterable[SimplexArg]) -> Iterator[pb.StreamRelationsRequest]:
    """One request per simplex; request_id is the simplex's index in the input.

    The relation is checked here, in the caller's thread: gRPC's sending thread, which takes
    the requests, would turn an error of its own into an UNKNOWN status without the message.
    (Arrays of simplices go in many-simplex messages: _batches.messages().)
    """
    code = relation(name)
    target = session_id(session)
    return (pb.StreamRelationsRequest(request_id=index, session_id=target, relation=code,
                                      simplex=simplex(value))
            for index, value in enumerate(values))


def decode_stream_relations(response: pb.StreamRelationsResponse,
                            raise_errors: bool) -> StreamItem:
    """The answer to one simplex of build_stream_relations(); its error is raised with
    `raise_errors`, else kept in the item."""
    error = None
    if response.HasField("error") and response.error.code:
        error = error_for_number(response.error.code, response.error.message)
        if raise_errors:
            raise error
    return StreamItem(int(response.request_id), np.array(response.ids, dtype=np.int64), error)


# Jobs.


def build_run_job(session: SessionRef, algorithm: Algorithm,
                  parameters: Mapping[str, Any] | None, include_arrays: bool,
                  trace: bool = False, digests: bool = False,
                  fields: FieldsArg = None) -> tuple[pb.RunJobRequest, Algorithm]:
    """The request, and the algorithm's name as the package spells it ("morse_smale" is
    "morse-smale"). `fields`: names or "all" for a job over several fields, None for the
    session's scalar field."""
    code = _names.lookup(_names.ALGORITHMS, algorithm, "algorithm")
    request = pb.RunJobRequest(session_id=session_id(session), algorithm=code,
                               parameters={str(k): str(v) for k, v in (parameters or {}).items()},
                               include_arrays=include_arrays, trace=trace, digests=digests,
                               **job_fields(fields))
    return request, cast(Algorithm, _names.name_of(_names.ALGORITHMS, code))


def build_cancel_job(job_id: str) -> pb.CancelJobRequest:
    return pb.CancelJobRequest(job_id=job_id)
