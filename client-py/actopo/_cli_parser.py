"""The `actopo` command line's grammar: the options every command takes, then one function per
command that adds its own, in the order of `actopo --help`. _cli runs the commands
(_cli.COMMANDS, by the name in ``args.command``)."""

from __future__ import annotations

import argparse
import math
import os
import re
import sys
from collections.abc import Sequence
from typing import Any, TypeAlias

from actopo import _names
from actopo._bench import MODES, ORDERS

STRUCTURES = list(_names.STRUCTURES)
ALGORITHMS = list(_names.ALGORITHMS)
DIAGRAM = "persistence-diagram"
DISTANCE = "diagram-distance"
TRACKING = "tracking"
MANY_FIELDS = (DISTANCE, TRACKING)
"""The algorithms that compare several fields: they run only with --scalars."""
TREES = ("merge-tree", "contour-tree")
"""The algorithms that give a tree (JobResult.tree), which --plot draws."""
TREE_TYPES = ("join", "split")
"""merge-tree's parameter "tree" (--tree): the join tree (the server's default) or the split
tree."""
PER_VERTEX = ("morse-smale", "topological-simplification", *TREES)
"""The algorithms whose --output files hold one value per vertex on the mesh
(PREFIX_segmentation.vtu, PREFIX_simplified.vtu): they need its geometry."""
SINGLE_FIELD = [a for a in ALGORITHMS if a not in MANY_FIELDS]
"""The algorithms that run on one field: those that `compare` and `bench` time."""

SERVER_DEFAULTS = {
    "--consumers": "one per server core",
    "--producers": "1",
    "--buffer-ratio": "0.2",
    "--query-readers": "one per server core, at most 4",
    "--block-size": "1000",
}
"""What the server takes for an option a command leaves out (the CLI then sends 0): its
WithDefaults (server/algorithms/structure_options.cc) and its octree's bucket capacity. The help
texts quote these; tests/test_cli_usage.py compares them with what a session and a mesh opened
with the defaults report."""
ENGINE_MAX = 64
"""The largest consumers, producers and query readers the server takes."""
INT32_MAX = 2**31 - 1
NEGATIVE_VALUE_FLAGS = ("--threshold", "--times")
"""Options whose value may start with '-' but is not a plain negative number ("-1%", "-1,2"),
which argparse would take for an option: parse_args() joins such a value to its flag."""

Commands: TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    """parser().parse_args(), with `--threshold -1%` read as `--threshold=-1%` (so the value
    reaches its check) rather than as a missing value."""
    args = list(sys.argv[1:] if argv is None else argv)
    joined: list[str] = []
    for arg in args:
        if joined and joined[-1] in NEGATIVE_VALUE_FLAGS and re.match(r"-[\d.]", arg):
            joined[-1] = f"{joined[-1]}={arg}"
        else:
            joined.append(arg)
    return parser().parse_args(joined)


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="actopo", description="Client of the ACTOPO topology "
                                "service: meshes, sessions, relations and algorithm jobs.")
    _add_connection(p)
    commands = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for add in (_add_info, _add_meshes, _add_load, _add_upload, _add_delete, _add_add_fields,
                _add_delete_field, _add_sessions, _add_open, _add_close, _add_run,
                _add_relation, _add_stats, _add_compare, _add_bench):
        add(commands)
    return p


def _add_connection(p: argparse.ArgumentParser) -> None:
    """Where the server is and how to reach it: the options before the command."""
    p.add_argument("--server", "--target", default=os.environ.get("ACTOPO_SERVER"),
                   metavar="HOST:PORT", help="actopo-server's address (default: $ACTOPO_SERVER)")
    p.add_argument("--token", default=os.environ.get("ACTOPO_TOKEN"),
                   help="bearer token (default: $ACTOPO_TOKEN)")
    p.add_argument("--affinity-key", default=os.environ.get("ACTOPO_AFFINITY_KEY"),
                   help="sent as x-actopo-session so a load balancer keeps this client on one "
                        "server replica (default: $ACTOPO_AFFINITY_KEY)")
    p.add_argument("--tls", action="store_true", help="use TLS with the system's roots")
    p.add_argument("--timeout", type=_positive(float), default=30.0,
                   help="deadline of quick calls in seconds (default 30)")


def _command(commands: Commands, name: str, help: str,
             json_flag: bool = True) -> argparse.ArgumentParser:
    """A command (_cli.COMMANDS runs it); it also takes --server after its name, and --json."""
    c = commands.add_parser(name, help=help, description=help)
    c.add_argument("--server", "--target", default=argparse.SUPPRESS, metavar="HOST:PORT",
                   help="actopo-server's address (also accepted before the command)")
    if json_flag:
        c.add_argument("--json", action="store_true", help="print JSON")
    return c


def _add_info(commands: Commands) -> None:
    _command(commands, "info", "versions, algorithms, relations, samples and limits")


def _add_meshes(commands: Commands) -> None:
    _command(commands, "meshes", "list the loaded meshes")


def _add_load(commands: Commands) -> None:
    c = _command(commands, "load",
                 "load a file under the server's data directory, a series given as its files, "
                 "or a sample; a local mesh file the server does not have is uploaded")
    c.add_argument("source", nargs="+", metavar="PATH",
                   help="path under the data directory (a local .vtu, .vtk, .vti or .pvd the "
                   "server does not have is uploaded), or sample:NAME (e.g. "
                   "sample:jittered:32); several paths: the files of a series (the same points "
                   "and tetrahedra), loaded as one mesh whose point fields are <field>_<k>, k "
                   "the file's index zero-padded to the width of the last (velocityMag_0 ... "
                   "velocityMag_3)")
    c.add_argument("--times", type=_list(float), metavar="T1,T2,...",
                   help="with several paths: each file's time value, in order (default: 0, 1, "
                   "...)")
    _add_block_size(c)
    c.add_argument("--block-labels", metavar="FIELD")
    _add_progress(c, "a progress bar per phase (read, partition, encode)")


def _add_upload(commands: Commands) -> None:
    c = _command(commands, "upload",
                 "upload a local mesh file: .vtu, .vtk, .vti and .pvd (with its files) as "
                 "their bytes, resumably; other formats read with pyvista or meshio")
    c.add_argument("file")
    c.add_argument("--name", help="the mesh's name (default: the file's; a .vtu, .vtk, .vti "
                   "or .pvd keeps its extension)")
    _add_block_size(c)
    c.add_argument("--block-labels", metavar="FIELD")
    _add_progress(c, "the bytes sent, then a bar per phase of the load")


def _add_delete(commands: Commands) -> None:
    c = _command(commands, "delete", "delete meshes", json_flag=False)
    c.add_argument("mesh_ids", nargs="+", metavar="MESH_ID")


def _add_add_fields(commands: Commands) -> None:
    c = _command(commands, "add-fields",
                 "add the point fields of a local mesh file (read with pyvista or meshio) to a "
                 "loaded mesh with the same vertices")
    c.add_argument("mesh_id", metavar="MESH_ID")
    c.add_argument("file", metavar="FILE")
    c.add_argument("--fields", type=_list(str), metavar="A,B,...",
                   help="the file's scalar point fields to add, comma-separated (default: all)")
    c.add_argument("--times", type=_list(float), metavar="T1,T2,...",
                   help="a time value per field added, in order (series members)")


def _add_delete_field(commands: Commands) -> None:
    c = _command(commands, "delete-field", "delete a point field of a loaded mesh")
    c.add_argument("mesh_id", metavar="MESH_ID")
    c.add_argument("name", metavar="NAME")


def _add_sessions(commands: Commands) -> None:
    _command(commands, "sessions", "list the open sessions")


def _add_open(commands: Commands) -> None:
    c = _command(commands, "open", "open a session that outlives the command")
    c.add_argument("mesh_id", metavar="MESH_ID")
    _add_engine(c)


def _add_close(commands: Commands) -> None:
    c = _command(commands, "close", "close sessions", json_flag=False)
    c.add_argument("session_ids", nargs="+", metavar="SESSION_ID")


def _add_run(commands: Commands) -> None:
    c = _command(commands, "run", "run an algorithm on a mesh and print its result; with "
                 "--scalars, over several fields, a line per field")
    which = c.add_mutually_exclusive_group(required=True)
    which.add_argument("algorithm_word", nargs="?", choices=ALGORITHMS, metavar="ALGORITHM",
                       help="the algorithm, as the first word or as --algorithm")
    which.add_argument("--algorithm", choices=ALGORITHMS)
    _add_mesh_source(c)
    _add_engine(c)
    c.add_argument("--scalars", type=_list(str), metavar="F1,F2,...|all",
                   help="run over these point fields one after the other (all: every "
                   f"floating-point field) instead of --scalar; {' and '.join(MANY_FIELDS)} "
                   "need two or more")
    _add_parameters(c, "an algorithm parameter (repeatable), e.g. embedding=domain "
                    "(persistence-diagram), relative_threshold=0.05 or persistence_threshold=2.5 "
                    "(topological-simplification; morse-smale, merge-tree and contour-tree of "
                    f"the simplified field; each field's own range with {DISTANCE}), "
                    "tree=split (merge-tree, as --tree), backend=legacy (TTK's whole-mesh "
                    "sweeps instead of its localized lts, for a simplification), p=1 and "
                    "essential=true "
                    f"({DISTANCE}), relations=all "
                    "(topo-relations: 22 relations instead of TTK's 20)")
    _add_run_outputs(c)
    _add_progress(c, "the load's and the job's progress bars")


def _add_parameters(c: argparse.ArgumentParser, param_help: str | None = None) -> None:
    """The algorithm's parameters: --boundary-rule, --tree, and --param NAME=VALUE
    (repeatable)."""
    c.add_argument("--boundary-rule", choices=["ttk", "none"], help="critical-points")
    c.add_argument("--tree", choices=TREE_TYPES,
                   help="merge-tree: the join tree (the server's default) or the split tree")
    c.add_argument("--param", action="append", type=_parameter, metavar="NAME=VALUE",
                   help=param_help)


def _add_run_outputs(c: argparse.ArgumentParser) -> None:
    """What `run` writes besides its report: ParaView files, a plot, a trace."""
    c.add_argument("--output", metavar="PREFIX",
                   help="write PREFIX_critical_points.vtp, ... for ParaView (PREFIX's directory "
                   "is created if missing, as --plot's and --trace's are); the segmentation and "
                   "the simplified field (PREFIX_segmentation.vtu, PREFIX_simplified.vtu) go "
                   "on the mesh: --upload's, --geometry's, --mesh NAME's file if found locally, "
                   "else its points and tetrahedra downloaded from the server")
    c.add_argument("--plot", metavar="PATH.png",
                   help=f"{DIAGRAM}: draw the diagram (birth, death) into this image with "
                   f"matplotlib (pip install 'actopo[plot]'); {' and '.join(TREES)}: the tree, "
                   "each node at its value, the persistence of its branches written beside "
                   f"their leaves; {DISTANCE}: the Wasserstein "
                   "matrix as a heat map (with a dendrogram when scipy is installed); "
                   f"{TRACKING}: the trajectories' extremum values over the steps")
    c.add_argument("--threshold", type=_threshold, metavar="T",
                   help="with --plot: draw the line death = birth + T; T is a persistence, or "
                   "a percentage of the scalar field's range such as 1%%")
    c.add_argument("--trace", metavar="FILE",
                   help="write a Chrome trace of the job's threads (block relations computed, "
                   "consumer waits, evictions, phases) for ui.perfetto.dev or chrome://tracing")
    c.add_argument("--digests", action="store_true",
                   help="add the result's SHA-256 digests (*_sha256, comparable with TTK's) to "
                   "the summary; they cost time on large meshes")
    c.add_argument("--geometry", metavar="FILE",
                   help="the mesh as a local file, for PREFIX_segmentation.vtu and "
                   "PREFIX_simplified.vtu (with its point fields); a file whose vertex or "
                   "tetrahedron count differs from the mesh's is refused before the job runs "
                   "(default: --mesh NAME, a series' first, under the current directory or "
                   "$ACTOPO_DATA_DIR if it is there and the same mesh, else the geometry "
                   "downloaded from the server)")


def _add_relation(commands: Commands) -> None:
    c = _command(commands, "relation", "a relation of some simplices")
    c.add_argument("relation", help=", ".join(_names.RELATIONS))
    c.add_argument("simplices", nargs="+", metavar="SIMPLEX",
                   help="an id, or a vertex tuple such as 3,17")
    c.add_argument("--vertices", action="store_true",
                   help="also print the vertices of result edges and triangles")
    _add_mesh_source(c, session=True)
    _add_engine(c)
    _add_progress(c, "the load's progress bars")


def _add_stats(commands: Commands) -> None:
    c = _command(commands, "stats", "statistics of one session, or of all")
    c.add_argument("--session", metavar="ID")


def _add_compare(commands: Commands) -> None:
    c = _command(commands, "compare",
                 "run an algorithm on several structures and compare time, wait and memory")
    _add_mesh_source(c)
    c.add_argument("--algorithm", required=True, choices=SINGLE_FIELD)
    c.add_argument("--structures", default=",".join(STRUCTURES),
                   help="comma-separated (default: all)")
    c.add_argument("--repeat", type=_positive(int), default=1,
                   help="runs per structure (median)")
    _add_engine(c, structure=False)
    _add_parameters(c)
    _add_progress(c, "the load's and the jobs' progress bars")


def _add_bench(commands: Commands) -> None:
    c = _command(commands, "bench",
                 "load a server from concurrent clients: unary, batched and streamed relation "
                 "queries and jobs; throughput, latency percentiles and the server's own time "
                 "breakdown")
    _add_mesh_source(c, required=False)
    _add_bench_sweep(c)
    _add_bench_requests(c)
    c.add_argument("--algorithm", default="critical-points", choices=SINGLE_FIELD,
                   help="the job of the job mode (default critical-points)")
    _add_parameters(c)
    _add_engine(c, structure=False)
    _add_progress(c, "the load's progress bars and a line per run")
    c.add_argument("--structures", help=argparse.SUPPRESS)  # now `compare`
    c.add_argument("--repeat", type=int, help=argparse.SUPPRESS)


def _add_bench_sweep(c: argparse.ArgumentParser) -> None:
    """What `bench` runs, and for how long: structures, modes, client counts, duration."""
    c.add_argument("--structure", type=_list(str, STRUCTURES), default=["actopo"],
                   help="comma-separated structures, one session each (default actopo)")
    c.add_argument("--modes", type=_list(str, MODES), default=list(MODES),
                   help=f"comma-separated, of {', '.join(MODES)} (default: all)")
    c.add_argument("--clients", type=_list(_positive(int)), default=[1],
                   help="concurrent clients, threads with a channel each; comma-separated for "
                        "a sweep, e.g. 1,4 (default 1)")
    c.add_argument("--duration", "--seconds", type=_positive(float), default=5.0,
                   metavar="SECONDS", help="per mode (default 5)")
    c.add_argument("--requests", type=_positive(int), metavar="N",
                   help="requests per client and mode, instead of a duration")


def _add_bench_requests(c: argparse.ArgumentParser) -> None:
    """What one request of `bench` asks: the relation, the ids, and the sizes per mode."""
    c.add_argument("--relation", default="vertex_star", choices=list(_names.RELATIONS),
                   metavar="NAME", help="the relation asked (default vertex_star), one of "
                   f"{', '.join(_names.RELATIONS)}")
    c.add_argument("--order", default="sequential", choices=ORDERS,
                   help="ids in order from a different start per client, or at random")
    c.add_argument("--batch-size", type=_positive(int), default=4096,
                   help="simplices per GetRelationBatch (default 4096)")
    c.add_argument("--stream-size", type=_positive(int), default=65536,
                   help="simplices per streamed array (default 65536)")
    c.add_argument("--chunk-size", type=_positive(int),
                   help="simplices per StreamRelations message (default 65536)")
    c.add_argument("--window", type=_positive(int), default=4,
                   help="StreamRelations messages in flight per client (default 4)")


# Option groups several commands share.


def _add_mesh_source(p: argparse.ArgumentParser, session: bool = False,
                     required: bool = True) -> None:
    g = p.add_mutually_exclusive_group(required=required)
    g.add_argument("--mesh", metavar="NAME", action="append",
                   help="a file under the server's data directory (a local .vtu, .vtk, .vti "
                   "or .pvd the server does not have is uploaded), or sample:NAME; repeated "
                   "(--mesh a.vtu --mesh b.vtu): the files of a series, loaded as one mesh "
                   "whose point fields are <field>_<k>, k the file's index zero-padded, time k")
    g.add_argument("--sample", metavar="NAME",
                   help="a built-in sample, e.g. wavelet:40 or sample:wavelet:40 (the same as "
                   "--mesh sample:wavelet:40); `actopo info` lists them")
    g.add_argument("--upload", metavar="FILE", help="a local mesh file to upload (.vtu, .vtk, "
                   ".vti, .pvd: as their bytes, resumably; others read with pyvista or meshio)")
    g.add_argument("--mesh-id", metavar="ID", help="a mesh already loaded on the server")
    if session:
        g.add_argument("--session", metavar="ID", help="an open session (see `actopo open`)")
    _add_block_size(p)
    p.add_argument("--keep", action="store_true",
                   help="keep the mesh this command loaded (default: delete it at the end)")


def _add_engine(p: argparse.ArgumentParser, structure: bool = True) -> None:
    if structure:
        p.add_argument("--structure", default="actopo", choices=STRUCTURES)
    p.add_argument("--scalar", help="scalar point field (default: first floating-point field)")
    p.add_argument("--consumers", type=_server_default(ENGINE_MAX), default=0,
                   help=f"algorithm threads, 1 to {ENGINE_MAX} "
                   f"{_default_help('--consumers')}")
    p.add_argument("--producers", type=_server_default(ENGINE_MAX), default=0,
                   help=f"actopo: producers per consumer, 1 to {ENGINE_MAX} "
                   f"{_default_help('--producers')}")
    p.add_argument("--buffer-ratio", type=_ratio, default=0.0,
                   help="cache/buffer capacity as a fraction of the blocks, 0 to 1 "
                   f"{_default_help('--buffer-ratio')}")
    p.add_argument("--prefetch", default="auto", choices=list(_names.PREFETCH))
    p.add_argument("--precompute", default="auto", choices=list(_names.PRECOMPUTE))
    p.add_argument("--query-readers", type=_server_default(ENGINE_MAX), default=0,
                   help=f"relation calls the session answers at once, 1 to {ENGINE_MAX} "
                   f"{_default_help('--query-readers')}")


def _add_block_size(p: argparse.ArgumentParser) -> None:
    p.add_argument("--block-size", type=_server_default(INT32_MAX), default=0, metavar="N",
                   help="octree bucket capacity (most vertices per block) when loading "
                   f"{_default_help('--block-size')}")


def _default_help(flag: str) -> str:
    """The help's "(default: the server's, X)", X from SERVER_DEFAULTS."""
    return f"(default: the server's, {SERVER_DEFAULTS[flag]})"


def _add_progress(p: argparse.ArgumentParser, what: str) -> None:
    p.add_argument("--progress", action=argparse.BooleanOptionalAction,
                   help=f"show {what} on stderr (default: when stderr is a terminal)")


# Types of options.


def _threshold(text: str) -> tuple[float, bool]:
    """An argparse type: a persistence, absolute ("0.68") or a percentage of the scalar field's
    range ("1%"); (value, whether it is a percentage)."""
    number = text.strip().removesuffix("%")
    try:
        value = float(number)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number or a percentage: '{text}'") from None
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f"must be a number >= 0, got {text}")
    return value, number != text.strip()


def _parameter(text: str) -> tuple[str, str]:
    """An argparse type: an algorithm parameter NAME=VALUE, as (NAME, VALUE)."""
    name, equals, value = text.partition("=")
    if not equals or not name.strip():
        raise argparse.ArgumentTypeError(f"'{text}' is not NAME=VALUE (e.g. --param "
                                         "embedding=domain)")
    return name.strip(), value


def _server_default(high: int) -> Any:
    """An argparse type: an integer from 0 (the server's default) to `high`."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not an integer: '{text}'") from None
        if not 0 <= value <= high:
            raise argparse.ArgumentTypeError(f"{value} is outside [0, {high}] (0: the server's "
                                             "default)")
        return value
    return parse


def _ratio(text: str) -> float:
    """An argparse type: a fraction from 0 (the server's default) to 1."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: '{text}'") from None
    if not 0 <= value <= 1:  # NaN too
        raise argparse.ArgumentTypeError(f"{text} is outside [0, 1] (0: the server's default)")
    return value


def _list(convert: Any, choices: Sequence[str] | None = None) -> Any:
    """An argparse type: comma-separated values, each converted and checked."""
    def parse(text: str) -> list[Any]:
        values = [convert(v.strip()) for v in text.split(",") if v.strip()]
        if not values:
            raise argparse.ArgumentTypeError("empty list")
        for v in values:
            if choices is not None and v not in choices:
                raise argparse.ArgumentTypeError(f"unknown '{v}'; choose from "
                                                 f"{', '.join(choices)}")
        return values
    return parse


def _positive(convert: Any) -> Any:
    """An argparse type: a positive number."""
    def parse(text: str) -> Any:
        try:
            value = convert(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: '{text}'") from None
        if value <= 0:
            raise argparse.ArgumentTypeError(f"must be positive, got {text}")
        return value
    return parse
