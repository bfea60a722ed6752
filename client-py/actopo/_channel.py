"""Channels: target resolution, TLS, keepalive, message sizes, deadlines and retries.

Retries. Every channel carries a gRPC service config ("grpc.service_config", with
"grpc.enable_retries" 1) whose retryPolicy retries the idempotent unary reads of
actopo.v1.TopologyService, RETRIED_METHODS (GetServerInfo, ListMeshes, GetMesh, ListSessions,
GetSession, GetSessionStats, GetRelation, GetRelationBatch, GetUpload), when an attempt ends
UNAVAILABLE: no connection (the server is restarting, or not there yet), a connection lost
before the answer, or a draining server ("shutting down; retry elsewhere"). Up to 5 attempts,
the retries after 0.2, 0.4, 0.8 and 1.6 s (each +-20%, gRPC's jitter), so about 3 s in all,
within the call's deadline. Nothing that creates, changes or deletes state is retried (LoadMesh,
UploadMesh, CreateUpload, OpenSession, RunJob, CancelJob, DeleteMesh, CloseSession), nor any
stream (LoadMeshWithProgress, StreamRelations, RunJob, WriteUpload); such a call fails with
UNAVAILABLE at once. A file upload (Client.upload_file) resumes a broken WriteUpload itself,
with this policy's attempts and backoff (_file_upload.Sender): it asks GetUpload what the
server holds and sends from there.

wait_for_ready is not set, neither on the channel nor per method: a read of a server that does
not come back fails with UNAVAILABLE after its ~3 s of attempts, rather than hanging until its
deadline. To let those attempts meet a restarted server, a lost or refused connection is
retried after 0.1 s, then at most every second (RECONNECT_OPTIONS; gRPC's defaults are 1 s,
growing to 2 min). So a read made while the server restarts succeeds when the server listens
again within about 2 s; the server's state (meshes, sessions, jobs) is gone, and reads of the
old ids end NOT_FOUND. A retried request is kept until answered, up to RETRY_BUFFER_BYTES (the
largest GetRelationBatch the clients send is 2 MiB); a larger one is sent once.

`retries=False` (Client, AsyncClient) leaves all of this out. Channel options given by the
caller replace these by name, e.g. ``("grpc.enable_retries", 0)`` or a "grpc.service_config"
of one's own.
"""

from __future__ import annotations

import json
import os
import uuid
from collections.abc import Sequence
from typing import Any, TypeAlias

import grpc
import grpc.aio

from actopo._errors import InvalidArgumentError

TlsArg: TypeAlias = bool | grpc.ChannelCredentials

DEFAULT_TIMEOUT = 30.0
"""Seconds for quick calls (info, lists, relations, stats)."""
MESH_TIMEOUT = 600.0
"""Seconds for calls that read, partition or preprocess a mesh (load, upload, open_session)."""
MAX_MESSAGE_BYTES = 256 << 20

# Keepalive: a ping every minute while calls are in flight (a job can be silent for long, and a
# dead peer should not hang the client), never on an idle channel; gRPC's default cap on pings
# without data keeps the client within a server's default ping policy.
_OPTIONS: list[tuple[str, Any]] = [
    ("grpc.keepalive_time_ms", 60_000),
    ("grpc.keepalive_timeout_ms", 20_000),
    ("grpc.keepalive_permit_without_calls", 0),
    ("grpc.max_receive_message_length", MAX_MESSAGE_BYTES),
    ("grpc.max_send_message_length", MAX_MESSAGE_BYTES),
]


SERVICE = "actopo.v1.TopologyService"
RETRIED_METHODS: tuple[str, ...] = (
    "GetServerInfo", "ListMeshes", "GetMesh", "ListSessions", "GetSession", "GetSessionStats",
    "GetRelation", "GetRelationBatch", "GetUpload",
)
"""The idempotent unary reads that the service config retries on UNAVAILABLE."""
RETRY_POLICY: dict[str, Any] = {
    "maxAttempts": 5,  # gRPC's most
    "initialBackoff": "0.2s",
    "maxBackoff": "2s",
    "backoffMultiplier": 2,
    "retryableStatusCodes": ["UNAVAILABLE"],
}
# Reconnection after a lost or refused connection: gRPC waits 1 s, then 1.6 times longer each
# time up to 2 min, and a read's attempts fail at once while it waits; 0.1 s, then at most 1 s,
# keeps a restarted server within reach of the ~3 s of attempts.
RECONNECT_OPTIONS: list[tuple[str, Any]] = [
    ("grpc.initial_reconnect_backoff_ms", 100),
    ("grpc.max_reconnect_backoff_ms", 1_000),
]
OWN_CONNECTION: tuple[str, Any] = ("grpc.use_local_subchannel_pool", 1)
"""The option that gives a channel a connection of its own (gRPC otherwise shares one among a
process's channels to the same target with the same options)."""
RETRY_BUFFER_BYTES = 4 << 20
"""Largest request kept for retrying (gRPC's default, 256 KiB, is less than a batch)."""


def service_config() -> str:
    """The JSON service config that retries RETRIED_METHODS (see the module docstring)."""
    names = [{"service": SERVICE, "method": method} for method in RETRIED_METHODS]
    return json.dumps({"methodConfig": [{"name": names, "retryPolicy": RETRY_POLICY}]})


def retry_options() -> list[tuple[str, Any]]:
    """The channel options that turn the retries on."""
    return [("grpc.enable_retries", 1), ("grpc.service_config", service_config()),
            ("grpc.per_rpc_retry_buffer_size", RETRY_BUFFER_BYTES), *RECONNECT_OPTIONS]


def resolve_target(target: str | None) -> str:
    """`target`, else $ACTOPO_SERVER; "host:port" (a scheme such as dns:/// is kept)."""
    resolved = target or os.environ.get("ACTOPO_SERVER", "")
    if not resolved:
        raise InvalidArgumentError("target: no server given: pass target='HOST:PORT' or set "
                                   "ACTOPO_SERVER")
    return resolved


def _credentials(tls: TlsArg) -> grpc.ChannelCredentials | None:
    if isinstance(tls, grpc.ChannelCredentials):
        return tls
    return grpc.ssl_channel_credentials() if tls else None


def channel_options(extra: Sequence[tuple[str, Any]],
                    retries: bool = True) -> list[tuple[str, Any]]:
    """The defaults (with the retry options unless `retries` is False), then `extra`, which
    replaces any default of the same name."""
    names = {name for name, _ in extra}
    defaults = _OPTIONS + (retry_options() if retries else [])
    return [o for o in defaults if o[0] not in names] + list(extra)


def sync_channel(target: str, tls: TlsArg, options: Sequence[tuple[str, Any]],
                 retries: bool = True) -> grpc.Channel:
    credentials = _credentials(tls)
    merged = channel_options(options, retries)
    if credentials is None:
        return grpc.insecure_channel(target, options=merged)
    return grpc.secure_channel(target, credentials, options=merged)


def async_channel(target: str, tls: TlsArg, options: Sequence[tuple[str, Any]],
                  retries: bool = True) -> grpc.aio.Channel:
    credentials = _credentials(tls)
    merged = channel_options(options, retries)
    if credentials is None:
        return grpc.aio.insecure_channel(target, options=merged)
    return grpc.aio.secure_channel(target, credentials, options=merged)


AFFINITY_HEADER = "x-actopo-session"


def metadata(token: str | None,
             affinity_key: str | None = None) -> tuple[tuple[str, str], ...]:
    """Per-call metadata: the bearer token, sent on plaintext and TLS channels alike, and the
    affinity key that a load balancer hashes (deploy/haproxy.cfg) so every call of this client
    reaches the same server, where its meshes and sessions live."""
    out: tuple[tuple[str, str], ...] = ()
    if token:
        out += (("authorization", f"Bearer {token}"),)
    if affinity_key:
        out += ((AFFINITY_HEADER, affinity_key),)
    return out


def client_metadata(token: str | None,
                    affinity_key: str | None) -> tuple[str, tuple[tuple[str, str], ...]]:
    """The affinity key a client uses (given, else $ACTOPO_AFFINITY_KEY, else a fresh random
    one, so everything one client creates stays on one replica behind a hashing balancer) and
    the metadata of its calls."""
    key = affinity_key or os.environ.get("ACTOPO_AFFINITY_KEY") or uuid.uuid4().hex
    return key, metadata(token, key)
