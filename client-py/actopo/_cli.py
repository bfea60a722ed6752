"""The `actopo` command line: a thin layer over Client.

    actopo --server HOST:PORT info | meshes | load | upload | delete | sessions | open | close
                              | run | relation | stats | bench

`--server` defaults to $ACTOPO_SERVER. Every listing command takes --json. Exit status: 0 on
success, 1 on a service error, 2 on a usage error, 130 on Ctrl-C (the running job is cancelled).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import statistics
import sys
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from actopo import _names
from actopo._client import Client, Session
from actopo._errors import ActopoError
from actopo._mesh import MeshArrays, mesh_arrays
from actopo._results import JobResult
from actopo._types import MeshInfo, SessionInfo, SessionStats, plain

STRUCTURES = list(_names.STRUCTURES)
ALGORITHMS = list(_names.ALGORITHMS)


def _print_json(value: Any) -> None:
    print(json.dumps(plain(value), indent=1))


def _table(rows: Sequence[Sequence[Any]], header: Sequence[str]) -> None:
    cells = [[str(c) for c in header]] + [[_cell(c) for c in row] for row in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(header))]
    for row in cells:
        print("  ".join(c.rjust(w) if i else c.ljust(w)
                        for i, (c, w) in enumerate(zip(row, widths))).rstrip())


def _cell(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.3f}"
    return str(value)


def _mib(n: int) -> str:
    return f"{n / 2**20:.1f} MiB"


# Mesh and session sources shared by run, relation and bench.


def _add_mesh_source(p: argparse.ArgumentParser, session: bool = False) -> None:
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--mesh", metavar="NAME",
                   help="a file under the server's data directory, or sample:NAME")
    g.add_argument("--upload", metavar="FILE", help="a local mesh file to upload")
    g.add_argument("--mesh-id", metavar="ID", help="a mesh already loaded on the server")
    if session:
        g.add_argument("--session", metavar="ID", help="an open session (see `actopo open`)")
    p.add_argument("--block-size", type=int, default=0,
                   help="octree bucket capacity when loading (default: the server's, 1000)")
    p.add_argument("--keep", action="store_true",
                   help="keep the mesh this command loaded (default: delete it at the end)")


def _add_engine(p: argparse.ArgumentParser, structure: bool = True) -> None:
    if structure:
        p.add_argument("--structure", default="actopo", choices=STRUCTURES)
    p.add_argument("--scalar", help="scalar point field (default: first floating-point field)")
    p.add_argument("--consumers", type=int, default=0, help="algorithm threads (default 1)")
    p.add_argument("--producers", type=int, default=0,
                   help="actopo: producers per consumer (default 2)")
    p.add_argument("--buffer-ratio", type=float, default=0.0,
                   help="cache/buffer capacity as a fraction of the blocks (default 0.2)")
    p.add_argument("--prefetch", default="auto", choices=list(_names.PREFETCH))
    p.add_argument("--precompute", default="auto", choices=list(_names.PRECOMPUTE))


class _Mesh:
    """The mesh a command works on; deletes it at the end if this command loaded it."""

    def __init__(self, info: MeshInfo, local: MeshArrays | None) -> None:
        self.info = info
        self.local = local


@contextlib.contextmanager
def _mesh(client: Client, args: argparse.Namespace) -> Iterator[_Mesh]:
    if args.mesh_id:
        yield _Mesh(client.get_mesh(args.mesh_id), None)
        return
    before = {m.mesh_id for m in client.list_meshes()}
    local = None
    if args.upload:
        local = mesh_arrays(args.upload, Path(args.upload).name)
        info = client.upload_mesh(local, block_size=args.block_size)
    else:
        info = client.load_mesh(args.mesh, block_size=args.block_size)
    try:
        yield _Mesh(info, local)
    finally:
        if info.mesh_id not in before and not args.keep:
            with contextlib.suppress(ActopoError):
                client.delete_mesh(info.mesh_id)


def _open(client: Client, mesh: MeshInfo, args: argparse.Namespace,
          structure: str | None = None) -> Session:
    return client.open_session(mesh, scalar=args.scalar, structure=structure or args.structure,
                               consumers=args.consumers, producers=args.producers,
                               buffer_ratio=args.buffer_ratio, prefetch=args.prefetch,
                               precompute=args.precompute)


def _geometry(args: argparse.Namespace, mesh: _Mesh) -> Any:
    """The local geometry for the segmentation file, when there is one."""
    if mesh.local is not None:
        return mesh.local
    if args.geometry:
        return args.geometry
    if args.mesh and not args.mesh.startswith("sample:"):
        for root in (Path.cwd(), Path(os.environ.get("ACTOPO_DATA_DIR", "") or "/nonexistent")):
            if (root / args.mesh).is_file():
                return root / args.mesh
    return None


# Commands.


def cmd_info(client: Client, args: argparse.Namespace) -> None:
    info = client.server_info()
    if args.json:
        return _print_json(info)
    print(f"server:      {client.target}, version {info.version}")
    for name, version in sorted(info.library_versions.items()):
        print(f"  {name}: {version}")
    print(f"algorithms:  {', '.join(info.algorithms)}")
    print(f"relations:   {', '.join(info.relations)}")
    print("samples:")
    for sample in info.samples:
        print(f"  {sample}")
    print("limits:")
    for key, value in plain(info.limits).items():
        print(f"  {key}: {value}")


def _mesh_rows(meshes: Sequence[MeshInfo]) -> None:
    _table([(m.mesh_id, m.name, m.vertices, m.tetrahedra, m.blocks,
             ",".join(f.name for f in m.fields), _mib(m.bytes), m.sessions) for m in meshes],
           ["MESH", "NAME", "VERTICES", "TETRAHEDRA", "BLOCKS", "FIELDS", "MEMORY", "SESSIONS"])


def cmd_meshes(client: Client, args: argparse.Namespace) -> None:
    meshes = client.list_meshes()
    if args.json:
        return _print_json(meshes)
    _mesh_rows(meshes)


def cmd_load(client: Client, args: argparse.Namespace) -> None:
    info = client.load_mesh(args.source, block_size=args.block_size,
                            block_label_field=args.block_labels or "")
    _print_json(info) if args.json else _mesh_rows([info])


def cmd_upload(client: Client, args: argparse.Namespace) -> None:
    info = client.upload_mesh(args.file, name=args.name or Path(args.file).name,
                              block_size=args.block_size,
                              block_label_field=args.block_labels or "")
    _print_json(info) if args.json else _mesh_rows([info])


def cmd_delete(client: Client, args: argparse.Namespace) -> None:
    for mesh_id in args.mesh_ids:
        client.delete_mesh(mesh_id)


def _session_rows(sessions: Sequence[SessionInfo]) -> None:
    _table([(s.session_id, s.mesh_id, s.scalar_field, s.structure, s.engine.consumers,
             s.engine.producers, s.engine.buffer_ratio, s.running_job_id or "-")
            for s in sessions],
           ["SESSION", "MESH", "SCALAR", "STRUCTURE", "CONSUMERS", "PRODUCERS", "BUFFER", "JOB"])


def cmd_sessions(client: Client, args: argparse.Namespace) -> None:
    sessions = client.list_sessions()
    if args.json:
        return _print_json(sessions)
    _session_rows(sessions)


def cmd_open(client: Client, args: argparse.Namespace) -> None:
    session = _open(client, client.get_mesh(args.mesh_id), args)
    _print_json(session.info) if args.json else _session_rows([session.info])


def cmd_close(client: Client, args: argparse.Namespace) -> None:
    for session_id in args.session_ids:
        client.close_session(session_id)


def _progress(args: argparse.Namespace) -> bool:
    return not args.no_progress and sys.stderr.isatty()


def _report(mesh: MeshInfo, session: Session, result: JobResult, stats: SessionStats,
            parameters: dict[str, str], wall: float) -> dict[str, Any]:
    """The JSON of `run`: actopo-bench's keys, with the service's numbers."""
    job = result.stats
    engine = job.engine if job else stats.engine
    memory = job.memory if job else stats.memory
    e = session.info.engine
    return {
        "mesh": {"mesh_id": mesh.mesh_id, "name": mesh.name, "source": mesh.source,
                 "vertices": mesh.vertices, "edges": mesh.edges, "triangles": mesh.triangles,
                 "tetrahedra": mesh.tetrahedra, "blocks": mesh.blocks},
        "structure": session.info.structure,
        "algorithm": result.algorithm,
        "config": {"consumers": e.consumers, "producers": e.producers, "prefetch": e.prefetch,
                   "precompute": e.precompute, "buffer_ratio": e.buffer_ratio,
                   "block_size": mesh.block_size, "scalar": session.info.scalar_field,
                   "parameters": parameters},
        "times_s": {"load": mesh.load_seconds, "partition": mesh.partition_seconds,
                    "preprocess": stats.preprocess_seconds,
                    "run": job.run_seconds if job else None, "total": wall},
        "engine": {"wait_s": engine.wait_seconds, "requests": engine.requests,
                   "hits": engine.hits, "misses": engine.misses, "evictions": engine.evictions,
                   "leader_relations": engine.leader_relations,
                   "worker_relations": engine.worker_relations,
                   "consumer_relations": engine.consumer_relations,
                   "duplicates_avoided": engine.duplicates_avoided,
                   "producer_busy_s": engine.producer_busy_ns / 1e9},
        "memory": {"process_rss_bytes": max(memory.process_rss_bytes,
                                            stats.memory.process_rss_bytes),
                   "static_bytes": memory.static_bytes,
                   "relation_peak_bytes": memory.relation_peak_bytes,
                   "buffer_peak_bytes": engine.buffer_peak_bytes},
        "job_id": result.job_id,
        "result": result.summary,
    }


def _parameters(args: argparse.Namespace) -> dict[str, str]:
    parameters = dict(p.split("=", 1) for p in args.param or [])
    if args.boundary_rule:
        parameters["boundary_rule"] = args.boundary_rule
    return parameters


def cmd_run(client: Client, args: argparse.Namespace) -> None:
    start = time.perf_counter()
    parameters = _parameters(args)
    with _mesh(client, args) as mesh, _open(client, mesh.info, args) as session:
        result = session.run(args.algorithm, parameters=parameters,
                             include_arrays=bool(args.output), progress=_progress(args))
        stats = session.stats()
        report = _report(mesh.info, session, result, stats, parameters,
                         time.perf_counter() - start)
        if args.output:
            geometry = _geometry(args, mesh)
            report["files"] = result.write(args.output, geometry)
            if result.segmentation and geometry is None:
                print("actopo: segmentation not written: the mesh geometry is on the server; "
                      "pass --geometry FILE (the same mesh, local)", file=sys.stderr)
    if args.json:
        return _print_json(report)
    print(f"{report['algorithm']} on {mesh.info.name} ({mesh.info.tetrahedra} tetrahedra, "
          f"{mesh.info.blocks} blocks), structure {report['structure']}, job {result.job_id}")
    print(f"  run {report['times_s']['run']:.3f} s, wait {report['engine']['wait_s']:.3f} s, "
          f"requests {report['engine']['requests']}, misses {report['engine']['misses']}, "
          f"relations peak {_mib(report['memory']['relation_peak_bytes'])}, "
          f"rss {_mib(report['memory']['process_rss_bytes'])}")
    print("result: " + json.dumps(result.summary, indent=1))
    for path in report.get("files", []):
        print(f"wrote {path}")


def _simplex(text: str) -> Any:
    parts = [int(p) for p in text.replace(" ", "").split(",") if p]
    return parts[0] if len(parts) == 1 and "," not in text else parts


@contextlib.contextmanager
def _session(client: Client, args: argparse.Namespace) -> Iterator[Session]:
    if args.session:
        yield client.session(args.session)
        return
    with _mesh(client, args) as mesh, _open(client, mesh.info, args) as session:
        yield session


def cmd_relation(client: Client, args: argparse.Namespace) -> None:
    simplices = [_simplex(s) for s in args.simplices]
    with _session(client, args) as session:
        answers = [session.query(args.relation, s, include_vertices=args.vertices)
                   for s in simplices]
    if args.json:
        return _print_json([{"simplex": s, "ids": a.ids, "vertices": a.vertices}
                            for s, a in zip(simplices, answers)])
    for s, a in zip(simplices, answers):
        text = " ".join(map(str, a.ids.tolist()))
        if a.vertices is not None:
            text += "  (" + " ".join(",".join(map(str, v)) for v in a.vertices.tolist()) + ")"
        print(f"{args.relation}({s}): {text}")


def cmd_stats(client: Client, args: argparse.Namespace) -> None:
    ids = [args.session] if args.session else [s.session_id for s in client.list_sessions()]
    stats = {i: client.session(i).stats() for i in ids}
    if args.json:
        return _print_json(stats)
    rows = []
    for i, s in stats.items():
        rows.append((i, s.jobs.count, s.relation_queries.count, s.preprocess_seconds,
                     s.engine.wait_seconds, f"{100 * s.engine.hit_rate:.1f}%", s.engine.misses,
                     _mib(s.memory.relation_peak_bytes), _mib(s.memory.process_rss_bytes)))
    _table(rows, ["SESSION", "JOBS", "QUERIES", "PREPROCESS_S", "WAIT_S", "HITS", "MISSES",
                  "RELATIONS_PEAK", "RSS"])


def cmd_bench(client: Client, args: argparse.Namespace) -> None:
    structures = [s.strip() for s in args.structures.split(",") if s.strip()]
    for s in structures:
        _names.lookup(_names.STRUCTURES, s, "structure")
    parameters = _parameters(args)
    rows, first = [], None
    with _mesh(client, args) as mesh:
        for structure in structures:
            with _open(client, mesh.info, args, structure) as session:
                runs = [session.run(args.algorithm, parameters=parameters, include_arrays=False,
                                    progress=_progress(args)) for _ in range(args.repeat)]
                stats = session.stats()
            first = first if first is not None else runs[0].summary
            job = [r.stats for r in runs if r.stats]
            rows.append({
                "structure": structure,
                "run_s": statistics.median(j.run_seconds for j in job) if job else None,
                "wait_s": statistics.median(j.engine.wait_seconds for j in job) if job else None,
                "preprocess_s": stats.preprocess_seconds,
                "requests": job[-1].engine.requests if job else 0,
                "hit_rate": job[-1].engine.hit_rate if job else 1.0,
                "relation_peak_bytes": stats.memory.relation_peak_bytes,
                "static_bytes": stats.memory.static_bytes,
                "process_rss_bytes": stats.memory.process_rss_bytes,
                "same_result": all(r.summary == first for r in runs),
                "result": runs[0].summary,
            })
    if args.json:
        return _print_json({"mesh": mesh.info, "algorithm": args.algorithm,
                            "repeat": args.repeat, "structures": rows})
    print(f"{args.algorithm} on {mesh.info.name}: {mesh.info.tetrahedra} tetrahedra, "
          f"{mesh.info.blocks} blocks, median of {args.repeat} run(s)")
    _table([(r["structure"], r["run_s"], r["wait_s"], r["preprocess_s"], r["requests"],
             f"{100 * r['hit_rate']:.1f}%", _mib(r["relation_peak_bytes"]),
             _mib(r["process_rss_bytes"]), "yes" if r["same_result"] else "DIFFERENT")
            for r in rows],
           ["STRUCTURE", "RUN_S", "WAIT_S", "PREPROCESS_S", "REQUESTS", "HITS",
            "RELATIONS_PEAK", "RSS", "SAME_RESULT"])


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="actopo", description="Client of the ACTOPO topology "
                                "service: meshes, sessions, relations and algorithm jobs.")
    p.add_argument("--server", default=os.environ.get("ACTOPO_SERVER"),
                   help="HOST:PORT of actopo-server (default: $ACTOPO_SERVER)")
    p.add_argument("--token", default=os.environ.get("ACTOPO_TOKEN"),
                   help="bearer token (default: $ACTOPO_TOKEN)")
    p.add_argument("--affinity-key", default=os.environ.get("ACTOPO_AFFINITY_KEY"),
                   help="sent as x-actopo-session so a load balancer keeps this client on one "
                        "server replica (default: $ACTOPO_AFFINITY_KEY)")
    p.add_argument("--tls", action="store_true", help="use TLS with the system's roots")
    p.add_argument("--timeout", type=float, default=30.0,
                   help="deadline of quick calls in seconds (default 30)")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def command(name: str, func: Any, help: str, json_flag: bool = True) -> Any:
        c = sub.add_parser(name, help=help, description=help)
        c.set_defaults(func=func)
        if json_flag:
            c.add_argument("--json", action="store_true", help="print JSON")
        return c

    command("info", cmd_info, "versions, algorithms, relations, samples and limits")
    command("meshes", cmd_meshes, "list the loaded meshes")
    c = command("load", cmd_load, "load a file under the server's data directory, or a sample")
    c.add_argument("source", help="path under the data directory, or sample:NAME "
                   "(e.g. sample:jittered:32)")
    c.add_argument("--block-size", type=int, default=0)
    c.add_argument("--block-labels", metavar="FIELD")
    c = command("upload", cmd_upload, "upload a local mesh file (read with pyvista or meshio)")
    c.add_argument("file")
    c.add_argument("--name")
    c.add_argument("--block-size", type=int, default=0)
    c.add_argument("--block-labels", metavar="FIELD")
    c = command("delete", cmd_delete, "delete meshes", json_flag=False)
    c.add_argument("mesh_ids", nargs="+", metavar="MESH_ID")
    command("sessions", cmd_sessions, "list the open sessions")
    c = command("open", cmd_open, "open a session that outlives the command")
    c.add_argument("mesh_id", metavar="MESH_ID")
    _add_engine(c)
    c = command("close", cmd_close, "close sessions", json_flag=False)
    c.add_argument("session_ids", nargs="+", metavar="SESSION_ID")

    c = command("run", cmd_run, "run an algorithm on a mesh and print its result")
    _add_mesh_source(c)
    c.add_argument("--algorithm", required=True, choices=ALGORITHMS)
    _add_engine(c)
    c.add_argument("--boundary-rule", choices=["ttk", "none"], help="critical-points")
    c.add_argument("--param", action="append", metavar="NAME=VALUE",
                   help="an algorithm parameter (repeatable)")
    c.add_argument("--output", metavar="PREFIX",
                   help="write PREFIX_critical_points.vtp, ... for ParaView")
    c.add_argument("--geometry", metavar="FILE",
                   help="the mesh as a local file, for PREFIX_segmentation.vtu with --mesh "
                   "(default: NAME under the current directory or $ACTOPO_DATA_DIR, if there)")
    c.add_argument("--no-progress", action="store_true", help="no progress bar")

    c = command("relation", cmd_relation, "a relation of some simplices")
    c.add_argument("relation", help=", ".join(_names.RELATIONS))
    c.add_argument("simplices", nargs="+", metavar="SIMPLEX",
                   help="an id, or a vertex tuple such as 3,17")
    c.add_argument("--vertices", action="store_true",
                   help="also print the vertices of result edges and triangles")
    _add_mesh_source(c, session=True)
    _add_engine(c)

    c = command("stats", cmd_stats, "statistics of one session, or of all")
    c.add_argument("--session", metavar="ID")

    c = command("bench", cmd_bench,
                "run an algorithm on several structures and compare time, wait and memory")
    _add_mesh_source(c)
    c.add_argument("--algorithm", required=True, choices=ALGORITHMS)
    c.add_argument("--structures", default=",".join(STRUCTURES),
                   help="comma-separated (default: all)")
    c.add_argument("--repeat", type=int, default=1, help="runs per structure (median)")
    _add_engine(c, structure=False)
    c.add_argument("--boundary-rule", choices=["ttk", "none"], help="critical-points")
    c.add_argument("--param", action="append", metavar="NAME=VALUE")
    c.add_argument("--no-progress", action="store_true")
    return p


def main(argv: Sequence[str] | None = None) -> int:
    args = parser().parse_args(argv)
    if not args.server:
        print("actopo: error: no server: pass --server HOST:PORT or set ACTOPO_SERVER",
              file=sys.stderr)
        return 2
    try:
        with Client(args.server, token=args.token, tls=args.tls, timeout=args.timeout,
                    affinity_key=args.affinity_key) as client:
            args.func(client, args)
    except ActopoError as e:
        print(f"actopo: error: {e}", file=sys.stderr)
        return 1
    except (ImportError, OSError, ValueError) as e:
        print(f"actopo: error: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("actopo: cancelled", file=sys.stderr)
        return 130
    return 0
