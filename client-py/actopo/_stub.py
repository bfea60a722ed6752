"""The service stub, typed: each RPC of actopo.v1.TopologyService with its request and response.

protoc writes the messages' types (topology_service_pb2.pyi) but leaves the service stub
(topology_service_pb2_grpc.py) untyped. Stub and AsyncStub say what each of its attributes is,
with the grpc and grpc.aio callable types of types-grpcio, so that a type checker checks every
request a client sends and every response it reads. The generated stub does the work at run
time; test_package.py checks these two lists against the service's descriptor (names, streaming
kinds, request and response types), so they cannot drift from ../proto.

    stub = sync_stub(channel)
    info = stub.GetServerInfo(pb.GetServerInfoRequest(), timeout=30)   # a GetServerInfoResponse
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Protocol, TypeVar, cast

import grpc
import grpc.aio

from actopo._proto import pb, pb_grpc

_T_co = TypeVar("_T_co", covariant=True)


class ResponseStream(Protocol[_T_co]):
    """What a blocking call of a server-streaming RPC returns: its responses, and cancel()."""

    def __iter__(self) -> Iterator[_T_co]: ...

    def __next__(self) -> _T_co: ...

    def cancel(self) -> bool: ...


class Stub(Protocol):
    """actopo.v1.TopologyService on a grpc.Channel (blocking calls)."""

    GetServerInfo: grpc.UnaryUnaryMultiCallable[pb.GetServerInfoRequest, pb.GetServerInfoResponse]
    LoadMesh: grpc.UnaryUnaryMultiCallable[pb.LoadMeshRequest, pb.LoadMeshResponse]
    LoadMeshWithProgress: grpc.UnaryStreamMultiCallable[pb.LoadMeshWithProgressRequest,
                                                        pb.LoadMeshWithProgressResponse]
    DownloadMesh: grpc.UnaryStreamMultiCallable[pb.DownloadMeshRequest, pb.DownloadMeshResponse]
    UploadMesh: grpc.StreamUnaryMultiCallable[pb.UploadMeshRequest, pb.UploadMeshResponse]
    CreateUpload: grpc.UnaryUnaryMultiCallable[pb.CreateUploadRequest, pb.CreateUploadResponse]
    WriteUpload: grpc.StreamUnaryMultiCallable[pb.WriteUploadRequest, pb.WriteUploadResponse]
    GetUpload: grpc.UnaryUnaryMultiCallable[pb.GetUploadRequest, pb.GetUploadResponse]
    DeleteUpload: grpc.UnaryUnaryMultiCallable[pb.DeleteUploadRequest, pb.DeleteUploadResponse]
    ListMeshes: grpc.UnaryUnaryMultiCallable[pb.ListMeshesRequest, pb.ListMeshesResponse]
    GetMesh: grpc.UnaryUnaryMultiCallable[pb.GetMeshRequest, pb.GetMeshResponse]
    DeleteMesh: grpc.UnaryUnaryMultiCallable[pb.DeleteMeshRequest, pb.DeleteMeshResponse]
    AddFields: grpc.StreamUnaryMultiCallable[pb.AddFieldsRequest, pb.AddFieldsResponse]
    DeleteField: grpc.UnaryUnaryMultiCallable[pb.DeleteFieldRequest, pb.DeleteFieldResponse]
    OpenSession: grpc.UnaryUnaryMultiCallable[pb.OpenSessionRequest, pb.OpenSessionResponse]
    GetSession: grpc.UnaryUnaryMultiCallable[pb.GetSessionRequest, pb.GetSessionResponse]
    ListSessions: grpc.UnaryUnaryMultiCallable[pb.ListSessionsRequest, pb.ListSessionsResponse]
    CloseSession: grpc.UnaryUnaryMultiCallable[pb.CloseSessionRequest, pb.CloseSessionResponse]
    GetSessionStats: grpc.UnaryUnaryMultiCallable[pb.GetSessionStatsRequest,
                                                  pb.GetSessionStatsResponse]
    GetRelation: grpc.UnaryUnaryMultiCallable[pb.GetRelationRequest, pb.GetRelationResponse]
    GetRelationBatch: grpc.UnaryUnaryMultiCallable[pb.GetRelationBatchRequest,
                                                   pb.GetRelationBatchResponse]
    StreamRelations: grpc.StreamStreamMultiCallable[pb.StreamRelationsRequest,
                                                    pb.StreamRelationsResponse]
    RunJob: grpc.UnaryStreamMultiCallable[pb.RunJobRequest, pb.RunJobResponse]
    CancelJob: grpc.UnaryUnaryMultiCallable[pb.CancelJobRequest, pb.CancelJobResponse]


class AsyncStub(Protocol):
    """actopo.v1.TopologyService on a grpc.aio.Channel (calls to await)."""

    GetServerInfo: grpc.aio.UnaryUnaryMultiCallable[pb.GetServerInfoRequest,
                                                    pb.GetServerInfoResponse]
    LoadMesh: grpc.aio.UnaryUnaryMultiCallable[pb.LoadMeshRequest, pb.LoadMeshResponse]
    LoadMeshWithProgress: grpc.aio.UnaryStreamMultiCallable[pb.LoadMeshWithProgressRequest,
                                                            pb.LoadMeshWithProgressResponse]
    DownloadMesh: grpc.aio.UnaryStreamMultiCallable[pb.DownloadMeshRequest,
                                                    pb.DownloadMeshResponse]
    UploadMesh: grpc.aio.StreamUnaryMultiCallable[pb.UploadMeshRequest, pb.UploadMeshResponse]
    CreateUpload: grpc.aio.UnaryUnaryMultiCallable[pb.CreateUploadRequest,
                                                   pb.CreateUploadResponse]
    WriteUpload: grpc.aio.StreamUnaryMultiCallable[pb.WriteUploadRequest,
                                                   pb.WriteUploadResponse]
    GetUpload: grpc.aio.UnaryUnaryMultiCallable[pb.GetUploadRequest, pb.GetUploadResponse]
    DeleteUpload: grpc.aio.UnaryUnaryMultiCallable[pb.DeleteUploadRequest,
                                                   pb.DeleteUploadResponse]
    ListMeshes: grpc.aio.UnaryUnaryMultiCallable[pb.ListMeshesRequest, pb.ListMeshesResponse]
    GetMesh: grpc.aio.UnaryUnaryMultiCallable[pb.GetMeshRequest, pb.GetMeshResponse]
    DeleteMesh: grpc.aio.UnaryUnaryMultiCallable[pb.DeleteMeshRequest, pb.DeleteMeshResponse]
    AddFields: grpc.aio.StreamUnaryMultiCallable[pb.AddFieldsRequest, pb.AddFieldsResponse]
    DeleteField: grpc.aio.UnaryUnaryMultiCallable[pb.DeleteFieldRequest,
                                                  pb.DeleteFieldResponse]
    OpenSession: grpc.aio.UnaryUnaryMultiCallable[pb.OpenSessionRequest, pb.OpenSessionResponse]
    GetSession: grpc.aio.UnaryUnaryMultiCallable[pb.GetSessionRequest, pb.GetSessionResponse]
    ListSessions: grpc.aio.UnaryUnaryMultiCallable[pb.ListSessionsRequest,
                                                   pb.ListSessionsResponse]
    CloseSession: grpc.aio.UnaryUnaryMultiCallable[pb.CloseSessionRequest,
                                                   pb.CloseSessionResponse]
    GetSessionStats: grpc.aio.UnaryUnaryMultiCallable[pb.GetSessionStatsRequest,
                                                      pb.GetSessionStatsResponse]
    GetRelation: grpc.aio.UnaryUnaryMultiCallable[pb.GetRelationRequest, pb.GetRelationResponse]
    GetRelationBatch: grpc.aio.UnaryUnaryMultiCallable[pb.GetRelationBatchRequest,
                                                       pb.GetRelationBatchResponse]
    StreamRelations: grpc.aio.StreamStreamMultiCallable[pb.StreamRelationsRequest,
                                                        pb.StreamRelationsResponse]
    RunJob: grpc.aio.UnaryStreamMultiCallable[pb.RunJobRequest, pb.RunJobResponse]
    CancelJob: grpc.aio.UnaryUnaryMultiCallable[pb.CancelJobRequest, pb.CancelJobResponse]


def sync_stub(channel: grpc.Channel) -> Stub:
    """The generated stub on a blocking channel, typed."""
    return cast(Stub, pb_grpc.TopologyServiceStub(channel))


def async_stub(channel: grpc.aio.Channel) -> AsyncStub:
    """The generated stub on an asyncio channel, typed."""
    return cast(AsyncStub, pb_grpc.TopologyServiceStub(channel))
