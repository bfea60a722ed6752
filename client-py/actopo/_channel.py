"""Channels: target resolution, TLS, keepalive, message sizes and deadlines."""

from __future__ import annotations

import os
import uuid
from collections.abc import Sequence
from typing import Any, TypeAlias

import grpc
import grpc.aio

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


def resolve_target(target: str | None) -> str:
    """`target`, else $ACTOPO_SERVER; "host:port" (a scheme such as dns:/// is kept)."""
    resolved = target or os.environ.get("ACTOPO_SERVER", "")
    if not resolved:
        raise ValueError("no server given: pass target='HOST:PORT' or set ACTOPO_SERVER")
    return resolved


def _credentials(tls: TlsArg) -> grpc.ChannelCredentials | None:
    if isinstance(tls, grpc.ChannelCredentials):
        return tls
    return grpc.ssl_channel_credentials() if tls else None


def _options(extra: Sequence[tuple[str, Any]]) -> list[tuple[str, Any]]:
    names = {name for name, _ in extra}
    return [o for o in _OPTIONS if o[0] not in names] + list(extra)


def sync_channel(target: str, tls: TlsArg, options: Sequence[tuple[str, Any]]) -> grpc.Channel:
    credentials = _credentials(tls)
    if credentials is None:
        return grpc.insecure_channel(target, options=_options(options))
    return grpc.secure_channel(target, credentials, options=_options(options))


def async_channel(target: str, tls: TlsArg,
                  options: Sequence[tuple[str, Any]]) -> grpc.aio.Channel:
    credentials = _credentials(tls)
    if credentials is None:
        return grpc.aio.insecure_channel(target, options=_options(options))
    return grpc.aio.secure_channel(target, credentials, options=_options(options))


AFFINITY_HEADER = "x-actopo-session"


def metadata(token: str | None,
             affinity_key: str | None = None) -> tuple[tuple[str, str], ...]:
    """Per-call metadata: the bearer token, sent on plaintext and TLS channels alike, and the
    affinity key that a load balancer hashes (deploy/envoy.yaml) so every call of this client
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
