#!/usr/bin/env python3
"""What a client waits for while a server builds a mesh's edges and triangles (faces on first
need): server builds in turn, medians of the runs.

    .venv/bin/python bench/faces_waits.py --data-dir /tmp/meshes --mesh wavelet128.vtu \\
        --runs 3 --server old=/tmp/old/build/server/cmd/actopo-server \\
        --server new=build/server/cmd/actopo-server

Each run starts every server in turn (A B A B ...), loads the mesh (without its faces) and
opens two compact sessions. On the first it starts a discrete-gradient job, the first thing to
read faces, so it builds them. `first_report_s`: from the job's start to its first progress
message, and that message's phase. As soon as the job is accepted, `--impatient` edge queries
on the second session, each needing the faces, with a `--deadline` deadline; `edge_failed_s`
until the last of them failed on the client (DEADLINE_EXCEEDED). Then one vertex-star query,
which needs no faces: `star_s`, how long it took. A server that lets waiting calls go at their
deadline has a relation thread free for it; one that does not holds both of its relation
threads in the edge queries until the build ends. `job_s`: the whole job, summary only.
"""
from __future__ import annotations

import argparse
import statistics
import threading
import time

import grpc
from service_mesh_memory import start_server

import actopo
from actopo._proto import pb, pb_grpc

FIGURES = ["first_report_s", "star_s", "edge_failed_s", "job_s"]


def measure(binary: str, args: argparse.Namespace) -> tuple[dict[str, float], str]:
    server, target = start_server(binary, args.data_dir)
    try:
        with actopo.Client(target) as client:
            mesh = client.load_mesh(args.mesh)
            jobs = client.open_session(mesh, structure="compact")
            queries = client.open_session(mesh, structure="compact")
            channel = grpc.insecure_channel(target)
            stub = pb_grpc.TopologyServiceStub(channel)
            accepted = threading.Event()
            figures: dict[str, float] = {}
            phase = ""

            def job() -> None:
                nonlocal phase
                start = time.perf_counter()
                request = pb.RunJobRequest(session_id=jobs.session_id,
                                           algorithm=pb.ALGORITHM_DISCRETE_GRADIENT,
                                           include_arrays=False)
                for response in stub.RunJob(request, timeout=600):
                    event = response.WhichOneof("event")
                    if event == "accepted":
                        accepted.set()
                    elif event == "progress" and "first_report_s" not in figures:
                        figures["first_report_s"] = time.perf_counter() - start
                        phase = response.progress.phase or "(none)"
                figures["job_s"] = time.perf_counter() - start

            running = threading.Thread(target=job)
            running.start()
            accepted.wait()
            edge = pb.GetRelationRequest(session_id=queries.session_id,
                                         relation=pb.RELATION_EDGE_VERTICES,
                                         simplex=pb.Simplex(id=7))
            futures = [stub.GetRelation.future(edge, timeout=args.deadline)
                       for _ in range(args.impatient)]
            start = time.perf_counter()
            for future in futures:
                try:
                    future.result()
                except grpc.RpcError as e:
                    assert e.code() == grpc.StatusCode.DEADLINE_EXCEEDED, e
            figures["edge_failed_s"] = time.perf_counter() - start
            start = time.perf_counter()
            star = pb.GetRelationRequest(session_id=queries.session_id,
                                         relation=pb.RELATION_VERTEX_STAR,
                                         simplex=pb.Simplex(id=0))
            stub.GetRelation(star, timeout=600)
            figures["star_s"] = time.perf_counter() - start
            running.join()
            channel.close()
            jobs.close()
            queries.close()
        return figures, phase
    finally:
        server.terminate()
        server.wait()


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--data-dir", required=True)
    p.add_argument("--mesh", required=True)
    p.add_argument("--runs", type=int, default=3)
    p.add_argument("--impatient", type=int, default=2,
                   help="edge queries with a short deadline (default 2: the relation threads)")
    p.add_argument("--deadline", type=float, default=0.05, help="their deadline, seconds")
    p.add_argument("--server", action="append", required=True, metavar="NAME=BINARY")
    args = p.parse_args()
    servers = dict(s.split("=", 1) for s in args.server)
    runs: dict[str, list[dict[str, float]]] = {name: [] for name in servers}
    phases: dict[str, set[str]] = {name: set() for name in servers}
    for run in range(args.runs):
        for name, binary in servers.items():
            figures, phase = measure(binary, args)
            runs[name].append(figures)
            phases[name].add(phase)
            print(f"run {run + 1} {name}: " +
                  ", ".join(f"{k} {figures[k]:.3f}" for k in FIGURES) + f", first phase {phase}",
                  flush=True)
    print("\nmedians (min-max) over", args.runs, "runs")
    for name in servers:
        cells = []
        for k in FIGURES:
            values = [r[k] for r in runs[name]]
            cells.append(f"{k} {statistics.median(values):.3f} "
                         f"({min(values):.3f}-{max(values):.3f})")
        print(f"{name}: " + ", ".join(cells) + f"; first phase {'/'.join(sorted(phases[name]))}")


if __name__ == "__main__":
    main()
