#!/usr/bin/env python3
"""grpc.health.v1 Check without generated stubs: exit 0 iff the server reports SERVING.

usage: grpc_health_check.py [HOST:PORT [SERVICE]]   (default 127.0.0.1:50051, service "")
Needs only the grpcio package (Debian's python3-grpcio has no health stubs): the request
(HealthCheckRequest{service}) is encoded and the reply (HealthCheckResponse{status}) decoded by
hand. Env: ACTOPO_HEALTH_TIMEOUT_S (default 3), ACTOPO_TOKEN (sent as a bearer token if set).
"""
import argparse
import os
import sys

import grpc

STATUS = {0: "UNKNOWN", 1: "SERVING", 2: "NOT_SERVING", 3: "SERVICE_UNKNOWN"}


def varint(data: bytes, pos: int) -> tuple[int, int]:
    value = shift = 0
    while True:
        byte = data[pos]
        pos += 1
        value |= (byte & 0x7F) << shift
        shift += 7
        if not byte & 0x80:
            return value, pos


def encode_request(service: str) -> bytes:
    raw = service.encode()
    if not raw:
        return b""
    length, out = len(raw), bytearray(b"\x0a")
    while length > 0x7F:
        out.append((length & 0x7F) | 0x80)
        length >>= 7
    out.append(length)
    return bytes(out) + raw


def decode_status(data: bytes) -> int:
    status, pos = 0, 0  # proto3: an absent field is 0 (UNKNOWN)
    while pos < len(data):
        key, pos = varint(data, pos)
        field, wire = key >> 3, key & 7
        if wire == 0:
            value, pos = varint(data, pos)
            if field == 1:
                status = value
        elif wire == 2:
            length, pos = varint(data, pos)
            pos += length
        elif wire in (1, 5):
            pos += 8 if wire == 1 else 4
        else:
            raise ValueError(f"unexpected wire type {wire}")
    return status


def main() -> int:
    parser = argparse.ArgumentParser(
        description="grpc.health.v1 Check: exit 0 iff the server reports SERVING, 1 otherwise "
                    "(2: a usage error). Env: ACTOPO_HEALTH_TIMEOUT_S (default 3), ACTOPO_TOKEN "
                    "(sent as a bearer token if set).")
    parser.add_argument("target", nargs="?", default="127.0.0.1:50051", metavar="HOST:PORT",
                        help="the server (default 127.0.0.1:50051)")
    parser.add_argument("service", nargs="?", default="", metavar="SERVICE",
                        help='the service asked about (default "": the whole server)')
    args = parser.parse_args()
    target, service = args.target, args.service
    timeout = float(os.environ.get("ACTOPO_HEALTH_TIMEOUT_S", "3"))
    token = os.environ.get("ACTOPO_TOKEN")
    metadata = [("authorization", f"Bearer {token}")] if token else None
    with grpc.insecure_channel(target) as channel:
        check = channel.unary_unary("/grpc.health.v1.Health/Check")  # bytes in, bytes out
        try:
            reply = check(encode_request(service), timeout=timeout, metadata=metadata)
        except grpc.RpcError as err:
            print(f"{target}: {err.code().name}: {err.details()}", file=sys.stderr)
            return 1
    status = decode_status(reply)
    print(f"{target}: {STATUS.get(status, status)}")
    return 0 if status == 1 else 1


if __name__ == "__main__":
    sys.exit(main())
