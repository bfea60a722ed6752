"""What adding a field to a loaded mesh costs against sending its bytes: the Python client's
`add_field` into a real actopo-server, against the same bytes in the same 1 MiB chunks sent
over the same client channel to a sink that only receives them (a Python gRPC server in its own
process, answering AddFields without parsing). Alternated, medians of --repeats.

    .venv/bin/python bench/add_fields_transfer.py --sample wavelet:128 --repeats 5
    # over a 1 Gb/s link: a network namespace behind a veth pair shaped by tc (root)
    ip netns add far && ip link add v0 type veth peer name v1 && ip link set v1 netns far
    ip addr add 10.77.0.1/24 dev v0 && ip link set v0 up
    ip netns exec far sh -c 'ip addr add 10.77.0.2/24 dev v1 && ip link set v1 up \
        && ip link set lo up && tc qdisc add dev v1 root tbf rate 1gbit burst 256kb latency 50ms'
    tc qdisc add dev v0 root tbf rate 1gbit burst 256kb latency 50ms
    .venv/bin/python bench/add_fields_transfer.py --netns far --host 10.77.0.2 --repeats 5

Prints JSON: add_field_s (checks, SHA-256, send, the server's decode, range and insert),
unchecked_s (the same bytes into the server without a digest: the server's own cost), bare_s
(the bytes alone, to the sink), client_messages_s (the client's own messages, hash included, to
the sink), their ratios and the bytes.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from concurrent import futures
from pathlib import Path

import grpc
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CHUNK = 1 << 20


def serve_sink(port_file: str, host: str) -> None:
    """A server whose AddFields reads every message as bytes and answers an empty response."""

    def add_fields(requests, context):  # type: ignore[no-untyped-def]
        for _ in requests:
            pass
        return b""

    handler = grpc.method_handlers_generic_handler("actopo.v1.TopologyService", {
        "AddFields": grpc.stream_unary_rpc_method_handler(add_fields)})
    server = grpc.server(futures.ThreadPoolExecutor(max_workers=2),
                         options=[("grpc.max_receive_message_length", 64 << 20)])
    server.add_generic_rpc_handlers((handler,))
    port = server.add_insecure_port(f"{host}:0")
    server.start()
    Path(port_file).write_text(str(port))
    server.wait_for_termination()


def wait_for_port(path: Path, process: subprocess.Popen[bytes]) -> int:
    for _ in range(600):
        if path.exists() and path.read_text().strip():
            return int(path.read_text())
        if process.poll() is not None:
            sys.exit(f"the sink ended with {process.returncode}")
        time.sleep(0.05)
    sys.exit("the sink did not start")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sample", default="wavelet:128")
    parser.add_argument("--dtype", default="float64", choices=["float64", "float32"])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--server", default=str(ROOT / "build/server/cmd/actopo-server"))
    parser.add_argument("--host", default="127.0.0.1",
                        help="address the servers listen on and the client connects to")
    parser.add_argument("--netns", help="run both servers in this network namespace (`ip netns "
                        "exec`), e.g. one behind a veth pair shaped to a link's rate")
    parser.add_argument("--sink", help=argparse.SUPPRESS)  # internal: run the sink
    args = parser.parse_args()
    if args.sink:
        serve_sink(args.sink, args.host)
        return

    sys.path.insert(0, str(ROOT / "client-py"))
    import actopo
    from actopo import _messages
    from actopo._arrays import code_of
    from actopo._proto.actopo.v1 import topology_service_pb2 as pb
    from actopo._proto.actopo.v1 import topology_service_pb2_grpc as pb_grpc

    scratch = Path(os.environ.get("TMPDIR", "/tmp")) / f"add_fields_transfer_{os.getpid()}"
    scratch.mkdir(parents=True, exist_ok=True)
    inside = ["ip", "netns", "exec", args.netns] if args.netns else []
    server = subprocess.Popen([*inside, args.server, "--host", args.host, "--port", "0"],
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    sink = subprocess.Popen([*inside, sys.executable, __file__, "--sink", str(scratch / "port"),
                             "--host", args.host])
    try:
        assert server.stdout is not None
        port = None
        for line in server.stdout:
            if "listening" in line:
                port = int(line.rsplit(":", 1)[1].split()[0])
                break
        if port is None:
            sys.exit("actopo-server did not start")
        sink_port = wait_for_port(scratch / "port", sink)
        client = actopo.Client(f"{args.host}:{port}")
        info = client.sample(args.sample)
        values = np.random.default_rng(0).random(info.vertices).astype(args.dtype)
        raw = values.tobytes()

        def bare_requests():  # type: ignore[no-untyped-def]
            for i in range(0, len(raw), CHUNK):
                yield pb.AddFieldsRequest(chunk=raw[i:i + CHUNK])

        sink_stub = pb_grpc.TopologyServiceStub(grpc.insecure_channel(
            f"{args.host}:{sink_port}", options=[("grpc.max_send_message_length", 64 << 20)]))

        def unchecked_requests():  # type: ignore[no-untyped-def]
            yield pb.AddFieldsRequest(header=pb.AddFieldsHeader(
                mesh_id=info.mesh_id, fields=[pb.UploadField(
                    name="added", dtype=code_of(values.dtype))]))
            yield from bare_requests()

        server_stub = pb_grpc.TopologyServiceStub(grpc.insecure_channel(
            f"{args.host}:{port}", options=[("grpc.max_send_message_length", 64 << 20)]))
        added, unchecked, bare, messages = [], [], [], []
        for k in range(args.repeats + 1):  # the first round warms both paths up
            start = time.perf_counter()
            client.add_field(info, "added", values)
            elapsed = time.perf_counter() - start
            client.delete_field(info, "added")
            start = time.perf_counter()
            server_stub.AddFields(unchecked_requests())
            unchecked_elapsed = time.perf_counter() - start
            client.delete_field(info, "added")
            start = time.perf_counter()
            sink_stub.AddFields(bare_requests())
            bare_elapsed = time.perf_counter() - start
            start = time.perf_counter()
            sink_stub.AddFields(_messages.build_add_fields(info, {"added": values},
                                                           info.vertices))
            messages_elapsed = time.perf_counter() - start
            if k > 0:
                added.append(elapsed)
                unchecked.append(unchecked_elapsed)
                bare.append(bare_elapsed)
                messages.append(messages_elapsed)
        client.delete_mesh(info)
        a, u, b, m = (statistics.median(x) for x in (added, unchecked, bare, messages))
        print(json.dumps({
            "sample": args.sample, "dtype": args.dtype, "vertices": info.vertices,
            "bytes": len(raw), "add_field_s": a, "unchecked_s": u, "bare_s": b,
            "client_messages_s": m, "add_field_over_bare": a / b, "unchecked_over_bare": u / b,
            "client_messages_over_bare": m / b,
            "add_field_mb_per_s": len(raw) / a / 1e6, "bare_mb_per_s": len(raw) / b / 1e6,
            "runs": {"add_field": added, "unchecked": unchecked, "bare": bare,
                     "client_messages": messages}}, indent=1))
    finally:
        server.terminate()
        sink.terminate()
        server.wait()
        sink.wait()


if __name__ == "__main__":
    main()
