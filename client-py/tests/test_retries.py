"""The retry policy of the client's channels, offline: the service config itself, and what it
does against a stand-in server (grpc's Python server, in process) that answers UNAVAILABLE a
given number of times. Fault tests against the real server are in test_faults.py."""

from __future__ import annotations

import asyncio
import json
from collections import Counter
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import grpc
import pytest

import actopo
from actopo import _channel
from actopo._proto import pb

READS = {"GetServerInfo", "ListMeshes", "GetMesh", "ListSessions", "GetSession",
         "GetSessionStats", "GetRelation", "GetRelationBatch", "GetUpload"}


def _method_config() -> dict[str, Any]:
    options = dict(_channel.channel_options([]))
    assert options["grpc.enable_retries"] == 1
    [config] = json.loads(options["grpc.service_config"])["methodConfig"]
    return config


def test_the_service_config_retries_only_idempotent_unary_reads():
    config = _method_config()
    assert {n["service"] for n in config["name"]} == {"actopo.v1.TopologyService"}
    assert {n["method"] for n in config["name"]} == READS
    service = pb.DESCRIPTOR.services_by_name["TopologyService"]
    for name in READS:
        method = service.methods_by_name[name]
        assert not method.client_streaming and not method.server_streaming, name
    policy = config["retryPolicy"]
    assert policy["retryableStatusCodes"] == ["UNAVAILABLE"]
    assert 2 <= policy["maxAttempts"] <= 5  # gRPC treats more as 5
    assert "waitForReady" not in config and "timeout" not in config


def test_retries_can_be_turned_off_or_replaced():
    off = dict(_channel.channel_options([], retries=False))
    assert "grpc.service_config" not in off and "grpc.enable_retries" not in off
    replaced = _channel.channel_options([("grpc.enable_retries", 0)])
    assert [v for k, v in replaced if k == "grpc.enable_retries"] == [0]


class FlakyServer:
    """TopologyService's GetServerInfo and DeleteMesh, failing UNAVAILABLE `failures` times
    per method before answering; counts the attempts."""

    def __init__(self, failures: int) -> None:
        self.failures = failures
        self.attempts: Counter[str] = Counter()
        self._server = grpc.server(ThreadPoolExecutor(4))
        handlers = {
            "GetServerInfo": self._handler("GetServerInfo", pb.GetServerInfoRequest,
                                           pb.GetServerInfoResponse(version="flaky")),
            "DeleteMesh": self._handler("DeleteMesh", pb.DeleteMeshRequest,
                                        pb.DeleteMeshResponse()),
        }
        self._server.add_generic_rpc_handlers(
            [grpc.method_handlers_generic_handler("actopo.v1.TopologyService", handlers)])
        self.target = f"127.0.0.1:{self._server.add_insecure_port('127.0.0.1:0')}"
        self._server.start()

    def _handler(self, method: str, request_type: Any, response: Any) -> grpc.RpcMethodHandler:
        def answer(request: Any, context: grpc.ServicerContext) -> Any:
            self.attempts[method] += 1
            if self.attempts[method] <= self.failures:
                context.abort(grpc.StatusCode.UNAVAILABLE, "restarting")
            return response
        return grpc.unary_unary_rpc_method_handler(
            answer, request_deserializer=request_type.FromString,
            response_serializer=lambda message: message.SerializeToString())

    def stop(self) -> None:
        self._server.stop(None)


@pytest.fixture
def flaky() -> Iterator[Callable[[int], FlakyServer]]:
    servers: list[FlakyServer] = []

    def start(failures: int) -> FlakyServer:
        servers.append(FlakyServer(failures))
        return servers[-1]

    yield start
    for server in servers:
        server.stop()


def test_a_read_is_retried_until_it_succeeds(flaky):
    server = flaky(2)
    with actopo.Client(server.target) as client:
        assert client.server_info().version == "flaky"
    assert server.attempts["GetServerInfo"] == 3


def test_a_read_gives_up_after_five_attempts(flaky):
    server = flaky(100)
    with actopo.Client(server.target) as client:
        with pytest.raises(actopo.UnavailableError, match="restarting"):
            client.server_info()
    assert server.attempts["GetServerInfo"] == 5


def test_a_write_is_never_retried(flaky):
    server = flaky(1)
    with actopo.Client(server.target) as client, pytest.raises(actopo.UnavailableError):
        client.delete_mesh("mesh-1")
    assert server.attempts["DeleteMesh"] == 1


def test_retries_false_tries_once(flaky):
    server = flaky(1)
    with actopo.Client(server.target, retries=False) as client:
        with pytest.raises(actopo.UnavailableError):
            client.server_info()
    assert server.attempts["GetServerInfo"] == 1


def test_the_async_client_retries_reads_too(flaky):
    server = flaky(2)

    async def main() -> str:
        async with actopo.AsyncClient(server.target) as client:
            return (await client.server_info()).version

    assert asyncio.run(main()) == "flaky"
    assert server.attempts["GetServerInfo"] == 3
