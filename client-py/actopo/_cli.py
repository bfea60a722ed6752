"""The `actopo` command line: a thin layer over Client (its options: _cli_parser).

    actopo --server HOST:PORT info | meshes | load | upload | delete | add-fields
                              | delete-field | sessions | open | close | run | relation
                              | stats | compare | bench

`--server` (or `--target`, before or after the command) defaults to $ACTOPO_SERVER. Every
listing command takes --json. Exit status: 0 on success, 1 on a service error (or a local file
that cannot be read), 2 on a usage error (argparse's, a value outside its range, options that do
not go together), 130 on Ctrl-C (the running load or job is cancelled on the server), 141 when
the reader of stdout went away (as SIGPIPE ends `cat`; nothing printed). `run` takes the
algorithm as `--algorithm NAME` or as its first word (`actopo run persistence-diagram ...`),
and with `--scalars F1,F2,...|all` runs it over several fields, a line per field as each is
done (`actopo run diagram-distance --scalars all` prints the distance matrices).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import signal
import statistics
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any, TypeAlias, cast

from actopo import _names, _tree
from actopo._bench import Bench, Load
from actopo._cli_parser import (
    DIAGRAM,
    MANY_FIELDS,
    PER_VERTEX,
    STRUCTURES,
    TRACKING,
    TREES,
    parse_args,
)
from actopo._client import Client, Session
from actopo._distances import DistanceMatrix
from actopo._errors import ActopoError, InvalidArgumentError, InvalidMeshError, NotFoundError
from actopo._fields import read_point_fields
from actopo._file_upload import is_mesh_file, pvd_files
from actopo._literals import Algorithm, Structure
from actopo._mesh import MeshArrays, mesh_arrays
from actopo._results import FieldResult, JobResult
from actopo._types import FieldInfo, MeshInfo, SessionInfo, SessionStats, plain


class UsageError(Exception):
    """A combination of arguments argparse cannot check (exit status 2, as argparse's own)."""


def _print_json(value: Any) -> None:
    print(json.dumps(plain(value), indent=1))


def _table(rows: Sequence[Sequence[Any]], header: Sequence[str]) -> None:
    cells = [[str(c) for c in header]] + [[_cell(c) for c in row] for row in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(header))]
    for row in cells:
        print("  ".join(c.rjust(w) if i else c.ljust(w)
                        for i, (c, w) in enumerate(zip(row, widths, strict=True))).rstrip())


def _cell(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.3f}"
    return str(value)


def _mib(n: int) -> str:
    return f"{n / 2**20:.1f} MiB"


# The mesh and session a command works on.


class _Mesh:
    """The mesh a command works on (deleted at the end if this command loaded it), with its
    arrays when the command uploaded them, or the local file it uploaded as its bytes."""

    def __init__(self, info: MeshInfo, local: MeshArrays | None,
                 file: Path | None = None) -> None:
        self.info = info
        self.local = local
        self.file = file


def _series(paths: list[str]) -> str | list[str]:
    """The paths of --mesh or `load`: one is a file (or sample:NAME), several the files of a
    series."""
    return paths[0] if len(paths) == 1 else paths


def _local_mesh_file(source: str | list[str]) -> Path | None:
    """The local file that a path of --mesh or `load` names, when there is one and the server
    reads it as it is (.vtu, .vtk, .vti, .pvd); None for a series, a sample or no such file."""
    if not isinstance(source, str) or source.startswith("sample:"):
        return None
    path = Path(source)
    return path if path.is_file() and is_mesh_file(path) else None


def _load_or_upload(client: Client, source: str | list[str], args: argparse.Namespace,
                    load: Callable[[], MeshInfo],
                    block_label_field: str = "") -> tuple[MeshInfo, Path | None]:
    """`load()`s a path of the server's data directory; a local mesh file that the server does
    not have (NOT_FOUND, or a path no data directory holds: absolute, or with '..') is
    uploaded as its bytes instead, with a note on stderr. The mesh, and the file uploaded."""
    local = _local_mesh_file(source)
    if local is None or not (local.is_absolute() or ".." in local.parts):
        try:
            return load(), None
        except NotFoundError:
            if local is None:
                raise
    print(f"actopo: {local} is not in the server's data directory: uploading the local file",
          file=sys.stderr)
    return client.upload_file(local, block_size=args.block_size,
                              block_label_field=block_label_field,
                              progress=_progress(args)), local


@contextlib.contextmanager
def _mesh(client: Client, args: argparse.Namespace) -> Iterator[_Mesh]:
    if args.mesh_id:
        yield _Mesh(client.get_mesh(args.mesh_id), None)
        return
    before = {m.mesh_id for m in client.list_meshes()}
    local, file = None, None
    if args.upload and is_mesh_file(args.upload):
        file = Path(args.upload)
        info = client.upload_file(file, block_size=args.block_size, progress=_progress(args))
    elif args.upload:
        local = mesh_arrays(args.upload, Path(args.upload).name)
        info = client.upload_mesh(local, block_size=args.block_size)
    else:
        source = _series(args.mesh) if args.mesh else _sample(args.sample)
        info, file = _load_or_upload(
            client, source, args,
            lambda: client.load_mesh(source, block_size=args.block_size,
                                     progress=_progress(args)))
    try:
        yield _Mesh(info, local, file)
    finally:
        if info.mesh_id not in before and not args.keep:
            with contextlib.suppress(ActopoError):
                client.delete_mesh(info.mesh_id)


def _sample(name: str) -> str:
    """--sample NAME, or --sample sample:NAME, as LoadMesh names a sample: sample:NAME."""
    return name if name.startswith("sample:") else f"sample:{name}"


def _explained(client: Client, error: ActopoError) -> ActopoError:
    """The server's error about the name of a mesh, with what a user needs next: for a path
    that is no file, the sample it may mean (a sample is sample:NAME); for a bad sample, the
    samples' names alone (the server's message describes each at length)."""
    missing = re.search(r"'([^']*)' not found in the data directory", error.details)
    sample = re.match(r"(sample '[^']*': .*?); samples: ", error.details)
    if not ((missing and isinstance(error, NotFoundError)) or sample):
        return error
    try:
        names = [s.split()[0] for s in client.server_info().samples if s.strip()]
    except ActopoError:
        return error
    if sample:
        return type(error)(f"{sample.group(1)}; samples: {', '.join(names)} (`actopo info` "
                           "describes them)", error.code)
    assert missing is not None
    path = missing.group(1)
    if path.split(":")[0] in [n.split(":")[0] for n in names]:
        hint = f"did you mean sample:{path}? (a built-in sample is sample:NAME)"
    elif not Path(path).suffix:
        hint = (f"a mesh file has an extension (.vtu, .vtk, .vti, .pvd), and a built-in sample "
                f"is sample:NAME, of {', '.join(names)}")
    else:
        return error
    return type(error)(f"{error.details}; {hint}", error.code)


def _structure(name: str) -> Structure:
    """A structure's name as the CLI got it, checked and spelled as the API spells it."""
    code = _names.lookup(_names.STRUCTURES, name.strip(), "structure")
    return cast(Structure, _names.name_of(_names.STRUCTURES, code))


def _open(client: Client, mesh: MeshInfo, args: argparse.Namespace,
          structure: Structure | None = None) -> Session:
    return client.open_session(mesh, scalar=args.scalar, structure=structure or args.structure,
                               consumers=args.consumers, producers=args.producers,
                               buffer_ratio=args.buffer_ratio, prefetch=args.prefetch,
                               precompute=args.precompute, query_readers=args.query_readers)


# The geometry of `run --output`'s per-vertex files (PREFIX_segmentation.vtu,
# PREFIX_simplified.vtu): --upload's mesh (or the local file --mesh uploaded), --geometry FILE,
# the file of --mesh NAME found locally, else the points and tetrahedra downloaded from the
# server.


def _mismatch(local: MeshArrays, info: MeshInfo) -> str | None:
    """How a local file's mesh differs from the server's in its counts, or None."""
    for what, here, there in (("vertices", len(local.points), info.vertices),
                              ("tetrahedra", len(local.tetrahedra), info.tetrahedra)):
        if here != there:
            return f"{here} {what}, but the mesh {info.name} on the server has {there}"
    return None


def _uploaded_geometry(file: Path, info: MeshInfo) -> MeshArrays | None:
    """The mesh of a file the command uploaded as its bytes (a .pvd's first file), read here
    when per-vertex files need it; None when it cannot be read here (no pyvista or meshio, an
    image the readers do not split) or holds other counts than the server's mesh."""
    try:
        if file.suffix.lower() == ".pvd":
            file = file.parent / pvd_files(file)[0]
        local = mesh_arrays(file)
    except (ActopoError, OSError, ImportError, IndexError):
        return None
    return local if _mismatch(local, info) is None else None


def _given_geometry(args: argparse.Namespace, mesh: _Mesh,
                    algorithm: Algorithm) -> MeshArrays | None:
    """The geometry the command has before the job: --upload's mesh, or the --geometry file
    read and checked against the mesh when the job writes per-vertex files (a file of another
    mesh stops the command here, before the job runs), or the file the command uploaded."""
    if mesh.local is not None:
        return mesh.local
    if not (args.output and algorithm in PER_VERTEX):
        return None
    if not args.geometry:
        return None if mesh.file is None else _uploaded_geometry(mesh.file, mesh.info)
    try:
        local = mesh_arrays(args.geometry)
    except (InvalidMeshError, FileNotFoundError) as e:
        raise InvalidArgumentError(f"--geometry: {e}") from None
    mismatch = _mismatch(local, mesh.info)
    if mismatch:
        raise InvalidArgumentError(f"--geometry {args.geometry}: {mismatch}; give the same "
                                   "mesh's file, or leave --geometry out to download the "
                                   "geometry from the server")
    return local


def _found_geometry(args: argparse.Namespace, info: MeshInfo) -> MeshArrays | None:
    """The file of --mesh NAME (a series' first: its files all hold the same points and
    tetrahedra) under the current directory or $ACTOPO_DATA_DIR, when it is there and holds
    the server's mesh; a file of another mesh by that name is passed over."""
    if not args.mesh or args.mesh[0].startswith("sample:"):
        return None
    roots = [Path.cwd()]
    if os.environ.get("ACTOPO_DATA_DIR"):
        roots.append(Path(os.environ["ACTOPO_DATA_DIR"]))
    for root in roots:
        if (root / args.mesh[0]).is_file():
            try:
                local = mesh_arrays(root / args.mesh[0])
            except (ActopoError, OSError, ImportError):
                return None
            return local if _mismatch(local, info) is None else None
    return None


def _write_output(client: Client, args: argparse.Namespace, mesh: _Mesh, result: JobResult,
                  geometry: MeshArrays | None) -> list[str]:
    """Writes --output's files; the per-vertex ones on `geometry`, else on the mesh's file
    found locally, else on the points and tetrahedra downloaded from the server (the arrays
    on them are the job's). Only a failed download leaves them out, with a warning."""
    per_vertex = [what for what, group in (("simplified field", result.group("simplified")),
                                           ("segmentation", result.segmentation)) if group]
    if per_vertex and geometry is None:
        geometry = _found_geometry(args, mesh.info)
    if per_vertex and geometry is None:
        try:
            geometry = client.download_mesh(mesh.info, progress=_progress(args))
        except ActopoError as e:
            print(f"actopo: {' and '.join(per_vertex)} not written: downloading the mesh's "
                  f"geometry failed ({e}); pass --geometry FILE (the same mesh, local)",
                  file=sys.stderr)
    return result.write(args.output, geometry)


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
    if args.times is not None and len(args.times) != max(len(args.source), 2):
        raise UsageError(f"--times: {len(args.times)} values for {len(args.source)} PATH(s); "
                         "give one per file of a series (two PATHs or more)")
    source = _series(args.source)
    info, _ = _load_or_upload(
        client, source, args,
        lambda: client.load_mesh(source, times=args.times, block_size=args.block_size,
                                 block_label_field=args.block_labels or "",
                                 progress=_progress(args)),
        block_label_field=args.block_labels or "")
    _print_json(info) if args.json else _mesh_rows([info])


def cmd_upload(client: Client, args: argparse.Namespace) -> None:
    if is_mesh_file(args.file):
        info = client.upload_file(args.file, name=args.name, block_size=args.block_size,
                                  block_label_field=args.block_labels or "",
                                  progress=_progress(args))
    else:
        info = client.upload_mesh(args.file, name=args.name or Path(args.file).name,
                                  block_size=args.block_size,
                                  block_label_field=args.block_labels or "")
    _print_json(info) if args.json else _mesh_rows([info])


def cmd_delete(client: Client, args: argparse.Namespace) -> None:
    for mesh_id in args.mesh_ids:
        client.delete_mesh(mesh_id)


def _field_rows(fields: Sequence[FieldInfo]) -> None:
    _table([(f.name, f.dtype, f.min, f.max, "-" if f.time is None else f"{f.time:g}")
            for f in fields], ["FIELD", "DTYPE", "MIN", "MAX", "TIME"])


def cmd_add_fields(client: Client, args: argparse.Namespace) -> None:
    found = read_point_fields(args.file)
    names = args.fields or list(found)
    missing = [name for name in names if name not in found]
    if missing:
        raise InvalidArgumentError(f"--fields: {args.file} has no scalar point field "
                                   f"'{missing[0]}' (it has: {', '.join(found) or 'none'})")
    info = client.add_fields(args.mesh_id, {name: found[name] for name in names},
                             times=args.times)
    _print_json(info) if args.json else _field_rows(info.fields)


def cmd_delete_field(client: Client, args: argparse.Namespace) -> None:
    info = client.delete_field(args.mesh_id, args.name)
    _print_json(info) if args.json else _field_rows(info.fields)


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
    """--progress, --no-progress, else whether stderr is a terminal."""
    return sys.stderr.isatty() if args.progress is None else args.progress


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
                    "faces": job.faces_seconds if job else None,
                    "run": job.run_seconds if job else None, "total": wall},
        "engine": {"wait_s": engine.wait_seconds, "requests": engine.requests,
                   "hits": engine.hits, "misses": engine.misses, "evictions": engine.evictions,
                   "leader_relations": engine.leader_relations,
                   "worker_relations": engine.worker_relations,
                   "consumer_relations": engine.consumer_relations,
                   "duplicates_avoided": engine.duplicates_avoided,
                   "waits_abandoned": engine.waits_abandoned,
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
    parameters = dict(args.param or [])  # (NAME, VALUE) pairs: _cli_parser._parameter
    if args.boundary_rule:
        parameters["boundary_rule"] = args.boundary_rule
    if args.tree:
        parameters["tree"] = args.tree
    return parameters


def _run_algorithm(args: argparse.Namespace) -> Algorithm:
    """The algorithm of `run` (--algorithm NAME or the first word), with the options that only
    some algorithms, or only one field, take checked against it."""
    algorithm = cast(Algorithm, args.algorithm or args.algorithm_word)
    if args.threshold is not None and not args.plot:
        raise UsageError("--threshold is the line of the plot: give --plot PATH.png too")
    if args.scalars and args.scalar:
        raise UsageError("--scalar and --scalars: give one (--scalars F1,F2,... runs over "
                         "several fields)")
    if algorithm in MANY_FIELDS and not args.scalars:
        raise UsageError(f"{algorithm} compares fields: give --scalars F1,F2,... or "
                         "--scalars all")
    if algorithm in (*MANY_FIELDS, *TREES) and args.threshold is not None:
        raise UsageError(f"--threshold draws on a persistence diagram; {algorithm} takes "
                         "--param persistence_threshold=T or --param relative_threshold=F")
    if args.plot and algorithm not in (DIAGRAM, *TREES, *MANY_FIELDS):
        raise UsageError(f"--plot draws a persistence diagram or a tree: run {DIAGRAM}, "
                         f"{' or '.join(TREES)}, not {algorithm}")
    if args.plot and args.scalars and algorithm not in MANY_FIELDS:
        what = "tree" if algorithm in TREES else "persistence diagram"
        raise UsageError(f"--plot draws one field's {what}: run without --scalars")
    if args.output and args.scalars:
        raise UsageError("--output writes one field's result: run without --scalars")
    return algorithm


def _make_directories(args: argparse.Namespace) -> None:
    """Creates the missing directories of --output PREFIX, --plot PATH and --trace FILE before
    the job runs (`--output out/fertility` in a fresh directory writes out/...)."""
    for path in (args.output, args.plot, args.trace):
        if path:
            Path(path).parent.mkdir(parents=True, exist_ok=True)


def _pair_counts(counts: dict[str, int]) -> str:
    """A diagram's counts_by_type as a reader says them: "type 0: 245 + 1 infinite, ..."."""
    parts = []
    for kind in range(3):
        finite, infinite = counts.get(str(kind), 0), counts.get(f"{kind}_infinite", 0)
        if finite or infinite:
            parts.append(f"type {kind}: {finite}" + (f" + {infinite} infinite" if infinite
                                                      else ""))
    return ", ".join(parts)


def _save_tree_plot(path: str, mesh: MeshInfo, scalar: str, result: JobResult) -> str:
    """Draws the job's tree into `path`, titled with the mesh, the field and the node types."""
    tree = result.tree
    if tree is None:
        raise ActopoError(f"job {result.job_id}: the server sent no tree arrays to plot")
    types = ", ".join(f"{_tree.CRITICAL_TYPES.get(int(kind), kind)}: {count}"
                      for kind, count in tree.counts_by_type().items())
    simplified = result.summary.get("simplification", {}).get("threshold")
    of = f"{scalar} simplified at {simplified:.4g}" if simplified is not None else scalar
    title = (f"{mesh.name}, {of}: {tree.kind} tree, {len(tree.nodes)} nodes, "
             f"{len(tree.arcs)} arcs\n{types}")
    return tree.save_plot(path, title=title)


def _save_plot(path: str, threshold: tuple[float, bool] | None, mesh: MeshInfo, scalar: str,
          result: JobResult) -> str:
    """Draws the job's persistence diagram, or its tree, into `path`. A percentage threshold is
    taken of the scalar field's range, as the server's relative_threshold of a simplification
    is."""
    if result.algorithm in TREES:
        return _save_tree_plot(path, mesh, scalar, result)
    diagram = result.diagram
    if diagram is None:
        raise ActopoError(f"job {result.job_id}: the server sent no diagram arrays to plot")
    line = None
    if threshold is not None:
        value, relative = threshold
        field = {f.name: f for f in mesh.fields}[scalar]
        line = value / 100 * (field.max - field.min) if relative else value
    title = (f"{mesh.name}, {scalar}: {len(diagram)} pairs\n"
             f"{_pair_counts(diagram.counts_by_type())}")
    return diagram.save_plot(path, threshold=line, title=title)


def cmd_run(client: Client, args: argparse.Namespace) -> None:
    start = time.perf_counter()
    algorithm = _run_algorithm(args)
    parameters = _parameters(args)
    _make_directories(args)
    if args.scalars:
        return _run_fields(client, args, algorithm, parameters, start)
    with _mesh(client, args) as mesh:
        geometry = _given_geometry(args, mesh, algorithm)
        with _open(client, mesh.info, args) as session:
            result = session.run(algorithm, parameters=parameters,
                                 include_arrays=bool(args.output or args.plot),
                                 trace=bool(args.trace), digests=args.digests,
                                 progress=_progress(args))
            stats = session.stats()
            # Described again: edges and triangles are counted once a job has built them (as
            # in actopo-bench's report, null when it needed none).
            report = _report(client.get_mesh(mesh.info), session, result, stats, parameters,
                             time.perf_counter() - start)
            if args.trace:
                report["trace"] = result.save_trace(args.trace)
            if args.plot:
                report["plot"] = _save_plot(args.plot, args.threshold, mesh.info,
                                            session.info.scalar_field, result)
            if args.output:
                report["files"] = _write_output(client, args, mesh, result, geometry)
    if args.json:
        return _print_json(report)
    print(f"{report['algorithm']} on {mesh.info.name} ({mesh.info.tetrahedra} tetrahedra, "
          f"{mesh.info.blocks} blocks), structure {report['structure']}, job {result.job_id}")
    faces = report["times_s"]["faces"]
    if faces:
        print(f"  faces {faces:.3f} s (the mesh's edges and triangles, built once per mesh)")
    print(f"  run {report['times_s']['run']:.3f} s, wait {report['engine']['wait_s']:.3f} s, "
          f"requests {report['engine']['requests']}, misses {report['engine']['misses']}, "
          f"relations peak {_mib(report['memory']['relation_peak_bytes'])}, "
          f"rss {_mib(report['memory']['process_rss_bytes'])}")
    print("result: " + json.dumps(result.summary, indent=1))
    for path in [*report.get("files", []), *([report["plot"]] if "plot" in report else [])]:
        print(f"wrote {path}")
    if "trace" in report:
        print(f"wrote {report['trace']} (open it in ui.perfetto.dev or chrome://tracing)")


def _field_line(result: FieldResult) -> str:
    """One field's line of `run --scalars`: its name, its run time and its summary."""
    return (f"  {result.field}: {result.run_seconds:.3f} s, "
            f"{json.dumps(result.summary, separators=(', ', ': '))}")


def _matrix_rows(name: str, values: Any, fields: Sequence[str]) -> None:
    print(f"{name}:")
    _table([(field, *(f"{v:.6g}" for v in row)) for field, row in zip(fields, values.tolist(),
                                                                         strict=True)],
           ["", *fields])


def _print_distances(matrix: DistanceMatrix, seconds: Any) -> None:
    essential = "matched" if matrix.essential else "left out"
    print(f"distances between {len(matrix)} persistence diagrams (p = {matrix.p:g}, infinite "
          f"pairs {essential}), {seconds or 0:.3f} s:")
    _matrix_rows(f"Wasserstein-{matrix.p:g}", matrix.wasserstein, matrix.fields)
    _matrix_rows("bottleneck", matrix.bottleneck, matrix.fields)
    print("pairs compared: " + ", ".join(map(str, matrix.pairs)))
    if any(matrix.thresholds):
        print("thresholds: " + ", ".join(f"{t:g}" for t in matrix.thresholds))


def _run_fields(client: Client, args: argparse.Namespace, algorithm: Algorithm,
                parameters: dict[str, str], start: float) -> None:
    """`run --scalars`: the job over several fields, a line per field as each is done (with
    --json one object with a "fields" list), and diagram-distance's matrices."""
    fields = "all" if args.scalars == ["all"] else args.scalars
    with _mesh(client, args) as mesh, _open(client, mesh.info, args) as session:
        # Only a tracking plot needs arrays: the trajectories.
        job = session.submit(algorithm, parameters=parameters,
                             include_arrays=algorithm == TRACKING and bool(args.plot),
                             trace=bool(args.trace), digests=args.digests, fields=fields)
        if not args.json:
            print(f"{algorithm} on {mesh.info.name} ({mesh.info.tetrahedra} tetrahedra, "
                  f"{mesh.info.blocks} blocks), structure {session.info.structure}, "
                  f"job {job.job_id}", flush=True)
        result = job._result(_progress(args), None if args.json else
                             lambda field: print(_field_line(field), flush=True))
        report = _report(client.get_mesh(mesh.info), session, result, session.stats(),
                         parameters, time.perf_counter() - start)
    report["config"]["scalars"] = [f.field for f in result.fields]
    report["fields"] = [{"field": f.field, "index": f.index, "run_s": f.run_seconds,
                         "result": f.summary} for f in result.fields]
    matrix = result.distance_matrix
    if args.trace:
        report["trace"] = result.save_trace(args.trace)
    if args.plot and matrix is not None:
        report["plot"] = matrix.plot(args.plot)
    if args.plot and result.tracking is not None:
        report["plot"] = result.tracking.plot(args.plot)
    if args.json:
        return _print_json(report)
    print(f"  run {report['times_s']['run']:.3f} s over {len(result.fields)} fields, wait "
          f"{report['engine']['wait_s']:.3f} s, rss "
          f"{_mib(report['memory']['process_rss_bytes'])}")
    if matrix is not None:
        _print_distances(matrix, result.summary.get("distance_seconds"))
    elif set(result.summary) != {"fields"}:  # a job that compares the fields, e.g. tracking
        print("result: " + json.dumps(result.summary, indent=1))
    if "plot" in report:
        print(f"wrote {report['plot']}")
    if "trace" in report:
        print(f"wrote {report['trace']} (open it in ui.perfetto.dev or chrome://tracing)")


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
                            for s, a in zip(simplices, answers, strict=True)])
    for s, a in zip(simplices, answers, strict=True):
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


def cmd_compare(client: Client, args: argparse.Namespace) -> None:
    structures = [_structure(s) for s in args.structures.split(",") if s.strip()]
    parameters = _parameters(args)
    rows: list[dict[str, Any]] = []
    first = None
    with _mesh(client, args) as mesh:
        for structure in structures:
            with _open(client, mesh.info, args, structure) as session:
                runs = [session.run(args.algorithm, parameters=parameters, include_arrays=False,
                                    progress=_progress(args)) for _ in range(args.repeat)]
                stats = session.stats()
            first = first if first is not None else runs[0].summary
            job = [r.stats for r in runs if r.stats]
            run_s = statistics.median(j.run_seconds for j in job) if job else None
            rows.append({
                "structure": structure,
                # What a user waits for on a new session: its preprocessing, then the job.
                "job_s": None if run_s is None else stats.preprocess_seconds + run_s,
                "run_s": run_s,
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
    _table([(r["structure"], r["job_s"], r["preprocess_s"], r["run_s"], r["wait_s"],
             r["requests"], f"{100 * r['hit_rate']:.1f}%", _mib(r["static_bytes"]),
             _mib(r["relation_peak_bytes"]), _mib(r["process_rss_bytes"]),
             "yes" if r["same_result"] else "DIFFERENT")
            for r in rows],
           ["STRUCTURE", "JOB_S", "PREPROCESS_S", "RUN_S", "WAIT_S", "REQUESTS", "HITS",
            "STATIC", "RELATIONS_PEAK", "SERVER_RSS", "SAME_RESULT"])


# bench: load from concurrent clients.

DEFAULT_BENCH_SAMPLE = "wavelet:30"


def _bench_connect(client: Client, args: argparse.Namespace) -> Any:
    """A factory of clients with channels (and connections) of their own, reaching the same
    server replica as `client` (the same affinity key)."""
    def connect() -> Client:
        return Client(client.target, token=args.token, tls=args.tls, timeout=args.timeout,
                      affinity_key=client.affinity_key,
                      options=[("grpc.use_local_subchannel_pool", 1)])
    return connect


def _number(value: float | None, digits: int = 0) -> str:
    return "-" if value is None else f"{value:,.{digits}f}"


def _bench_rows(rows: Sequence[dict[str, Any]]) -> None:
    table = []
    for r in rows:
        server, latency = r["server"], r["latency_ms"]
        job = r["mode"] == "job"
        per = server.get("per_simplex_ns", {})
        table.append((
            r["structure"], r["mode"], r["clients"], r["requests"], r["errors"],
            _number(r["requests_per_s"], 1), _number(r["simplices_per_s"]),
            *(_number(latency[k], 3) for k in ("p50", "p90", "p99", "p99.9")),
            server["jobs"]["count"] if job else server["relation_queries"]["count"],
            *(_number(None if job else per[k], 1) for k in ("queue", "compute", "serialize"))))
    _table(table, ["STRUCTURE", "MODE", "CLIENTS", "REQUESTS", "ERRORS", "REQ/S", "SIMPLICES/S",
                   "P50_MS", "P90_MS", "P99_MS", "P99.9_MS", "SERVER_CALLS", "QUEUE_NS",
                   "COMPUTE_NS", "SERIALIZE_NS"])


def cmd_bench(client: Client, args: argparse.Namespace) -> None:
    if args.structures or args.repeat:  # how `compare` was called before it had its name
        print("actopo: note: `bench --structures/--repeat` is now `actopo compare`",
              file=sys.stderr)
        args.structures = args.structures or ",".join(STRUCTURES)
        args.repeat = args.repeat or 1
        return cmd_compare(client, args)
    if not (args.mesh or args.upload or args.mesh_id or args.sample):
        args.sample = DEFAULT_BENCH_SAMPLE
    limit = client.server_info().limits.max_batch_size
    if "batch" in args.modes and limit and args.batch_size > limit:
        raise InvalidArgumentError(f"--batch-size: {args.batch_size} is over the server's "
                                   f"max_batch_size of {limit}")
    load = Load(relation=args.relation, seconds=args.duration, requests=args.requests or 0,
                batch_size=args.batch_size, stream_size=args.stream_size,
                chunk_size=args.chunk_size, window=args.window, order=args.order,
                algorithm=args.algorithm, parameters=_parameters(args))
    rows: list[dict[str, Any]] = []
    with _mesh(client, args) as mesh:
        bench = Bench(_bench_connect(client, args),
                      lambda c, structure: _open(c, mesh.info, args, structure), mesh.info, load)
        for structure in args.structure:
            with contextlib.ExitStack() as stack:
                shared = None
                if any(m != "job" for m in args.modes):
                    shared = stack.enter_context(_open(client, mesh.info, args, structure))
                for clients in args.clients:
                    for mode in args.modes:
                        rows.append(bench.run(structure, mode, clients, shared))
                        if _progress(args):
                            r = rows[-1]
                            print(f"actopo bench: {structure} {mode} x{clients}: "
                                  f"{_number(r['requests_per_s'], 1)} req/s", file=sys.stderr)
    m = mesh.info
    report = {
        "target": client.target,
        "mesh": {"mesh_id": m.mesh_id, "name": m.name, "source": m.source,
                 "vertices": m.vertices, "edges": m.edges, "triangles": m.triangles,
                 "tetrahedra": m.tetrahedra, "blocks": m.blocks},
        "config": {"relation": args.relation, "order": args.order,
                   "duration_s": None if args.requests else args.duration,
                   "requests_per_client": args.requests, "batch_size": args.batch_size,
                   "stream_size": args.stream_size, "chunk_size": args.chunk_size,
                   "window": args.window, "algorithm": args.algorithm,
                   "parameters": load.parameters, "query_readers": args.query_readers},
        "runs": rows,
    }
    if args.json:
        return _print_json(report)
    span = f"{args.requests} requests per client" if args.requests else f"{args.duration:g} s"
    print(f"{args.relation} on {m.name}: {m.vertices} vertices, {m.tetrahedra} tetrahedra, "
          f"{m.blocks} blocks; {span} per mode, {args.order} ids, batch {args.batch_size}, "
          f"stream arrays of {args.stream_size}; jobs: {args.algorithm}")
    _bench_rows(rows)
    print("REQ/S: calls (unary, batch), arrays (stream) or jobs per second; latencies in ms.\n"
          "SERVER_CALLS: the server's relation calls (jobs for job); QUEUE_NS, COMPUTE_NS, "
          "SERIALIZE_NS: its time per simplex.")
    errors = [r for r in rows if r["first_error"]]
    for r in errors:
        print(f"{r['structure']} {r['mode']} x{r['clients']}: first error: {r['first_error']}",
              file=sys.stderr)


Command: TypeAlias = Callable[[Client, argparse.Namespace], None]
COMMANDS: dict[str, Command] = {
    "info": cmd_info, "meshes": cmd_meshes, "load": cmd_load, "upload": cmd_upload,
    "delete": cmd_delete, "add-fields": cmd_add_fields, "delete-field": cmd_delete_field,
    "sessions": cmd_sessions, "open": cmd_open, "close": cmd_close,
    "run": cmd_run, "relation": cmd_relation, "stats": cmd_stats, "compare": cmd_compare,
    "bench": cmd_bench,
}
"""What each command of _cli_parser.parser() runs."""


def main(argv: Sequence[str] | None = None) -> int:
    try:
        status = _main(argv)
        sys.stdout.flush()  # so that a closed pipe shows here, not as the interpreter exits
        return status
    except BrokenPipeError:
        return _stdout_closed()
    except KeyboardInterrupt:
        print("actopo: cancelled", file=sys.stderr)
        return 130


def _stdout_closed() -> int:
    """The reader of stdout went away (`actopo stats --json | head -1`): the command ends
    quietly with the status of a program that SIGPIPE stopped, 128 + 13, as `cat` in a shell
    pipe reports it (a pipeline under `set -o pipefail` sees the same as with `cat`). stdout then
    points at /dev/null, so the interpreter's last flush does not fail again."""
    os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return 128 + signal.SIGPIPE


def _main(argv: Sequence[str] | None) -> int:
    args = parse_args(argv)
    if not args.server:
        print("actopo: error: no server: pass --server HOST:PORT or set ACTOPO_SERVER",
              file=sys.stderr)
        return 2
    try:
        with Client(args.server, token=args.token, tls=args.tls, timeout=args.timeout,
                    affinity_key=args.affinity_key) as client:
            try:
                COMMANDS[args.command](client, args)
            except (NotFoundError, InvalidArgumentError) as e:
                raise _explained(client, e) from None
    except UsageError as e:
        print(f"actopo: error: {e}", file=sys.stderr)
        return 2
    except ActopoError as e:
        print(f"actopo: error: {e}", file=sys.stderr)
        return 1
    except BrokenPipeError:
        raise  # main()'s
    except (ImportError, OSError, ValueError) as e:
        print(f"actopo: error: {e}", file=sys.stderr)
        return 1
    return 0
