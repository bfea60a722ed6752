"""The package's shape, without a server: the public names against README.md, the Literal
types against the proto's enums, the checks of names at run time, the module import graph and
the ratio convention."""

from __future__ import annotations

import ast
import asyncio
import re
import subprocess
import sys
from collections.abc import Callable
from dataclasses import MISSING, fields
from pathlib import Path
from typing import Any, get_args

import grpc
import pytest

import actopo
import actopo.types
from actopo import _literals, _messages, _names, _requests, _stub
from actopo._proto import pb, pb_grpc

PACKAGE = Path(actopo.__file__).resolve().parent
README = PACKAGE.parent / "README.md"


def _documented() -> dict[str, list[str]]:
    """The names listed under "### Public names" in README.md: the bullets of the section
    itself under "actopo", those of its "#### `actopo.types`" part under "actopo.types"."""
    lines = README.read_text().splitlines()
    start = lines.index("### Public names")
    listed: dict[str, list[str]] = {"actopo": [], "actopo.types": []}
    module = "actopo"
    for line in lines[start + 1:]:
        if line.startswith(("## ", "### ")):
            break
        if line.startswith("#### "):
            module = line[len("#### "):].strip("`")
            assert module in listed, f"README.md: unexpected part '{line}' in Public names"
        match = re.match(r"- `(\w+)`: \S", line)
        if match:
            listed[module].append(match.group(1))
    return listed


def test_all_is_the_documented_list():
    documented = _documented()["actopo"]
    assert len(documented) == len(set(documented)), "a name is listed twice in README.md"
    assert sorted(actopo.__all__) == sorted(documented)
    for name in actopo.__all__:
        assert hasattr(actopo, name), name


def test_types_all_is_the_documented_list():
    documented = _documented()["actopo.types"]
    assert len(documented) == len(set(documented)), "a name is listed twice in README.md"
    assert sorted(actopo.types.__all__) == sorted(documented)
    for name in actopo.types.__all__:
        assert hasattr(actopo.types, name), name
    # What the top level shares with actopo.types is the same object.
    for name in set(actopo.__all__) & set(actopo.types.__all__):
        assert getattr(actopo, name) is getattr(actopo.types, name), name


def test_private_modules_are_not_exported():
    exported = set(actopo.__all__) | set(actopo.types.__all__)
    assert not {name for name in exported if name.startswith("_") and name != "__version__"}


# (Literal type, the package's name table, the proto enum, its prefix, whether "auto" means
# the enum's UNSPECIFIED value).
LITERALS = [
    (actopo.Structure, _names.STRUCTURES, pb.Structure, "STRUCTURE_", False),
    (actopo.Algorithm, _names.ALGORITHMS, pb.Algorithm, "ALGORITHM_", False),
    (actopo.Relation, _names.RELATIONS, pb.Relation, "RELATION_", False),
    (actopo.Prefetch, _names.PREFETCH, pb.Prefetch, "PREFETCH_", True),
    (actopo.Precompute, _names.PRECOMPUTE, pb.Precompute, "PRECOMPUTE_", True),
]


@pytest.mark.parametrize("literal,table,enum,prefix,auto", LITERALS,
                         ids=[e[3].rstrip("_").lower() for e in LITERALS])
def test_literal_values_are_the_proto_names(literal, table, enum, prefix, auto):
    values = get_args(literal)
    assert len(values) == len(set(values))
    # The same names, in the proto's order, as the package maps them to enum values ...
    assert list(values) == list(table)
    # ... and every value of the enum has one: a new proto value needs a Literal value.
    mapped = set(enum.values()) - ({0} if not auto else set())
    assert set(table.values()) == mapped
    for name in values:
        code = _names.lookup(table, name, "name")
        expected = "UNSPECIFIED" if name == "auto" else name.upper().replace("-", "_")
        assert enum.Name(code) == prefix + expected


def test_literals_are_exported_where_they_are_defined():
    for name in ("Structure", "Algorithm", "Relation", "Prefetch", "Precompute"):
        assert getattr(actopo, name) is getattr(_literals, name)
        assert name in actopo.__all__


class _Offline:
    """A client of a port nobody listens on: every check below fails before any call."""

    def __init__(self) -> None:
        self.client = actopo.Client("127.0.0.1:9", retries=False, timeout=1.0)
        self.session = actopo.Session(self.client, self.info())

    @staticmethod
    def info() -> actopo.types.SessionInfo:
        return actopo.types.SessionInfo(
            session_id="session-x", mesh_id="mesh-x", scalar_field="", structure="actopo",
            engine=actopo.types.EngineOptions(consumers=1, producers=1, buffer_ratio=0.2,
                                              prefetch="auto", precompute="auto"),
            created=None, last_used=None, running_job_id=None)


BAD_NAMES: list[tuple[str, str, Callable[[_Offline], Any]]] = [
    ("structure", "fancy", lambda o: o.client.open_session("mesh-x", structure="fancy")),
    ("prefetch", "sideways", lambda o: o.client.open_session("mesh-x", prefetch="sideways")),
    ("precompute", "always", lambda o: o.client.open_session("mesh-x", precompute="always")),
    ("relation", "vv", lambda o: o.session.query("vv", 0)),
    ("relation", "vertex_stars", lambda o: list(o.session.relations_stream("vertex_stars", [0]))),
    ("algorithm", "reeb-graph", lambda o: o.session.submit("reeb-graph")),
    ("structure", "3",
     lambda o: _messages.build_open_session("m", None, 3, 0, 0, 0.0, "auto", "auto")),
]


@pytest.mark.parametrize("parameter,value,call", BAD_NAMES,
                         ids=[f"{p}={v}" for p, v, _ in BAD_NAMES])
def test_unknown_names_raise_naming_parameter_and_value(parameter, value, call):
    offline = _Offline()
    try:
        with pytest.raises(actopo.InvalidArgumentError) as e:
            call(offline)
    finally:
        offline.client.close()
    assert e.value.code is None  # decided by the client, not by a server
    assert f"{parameter}: unknown {parameter} '{value}'; available: " in str(e.value)


def test_unknown_names_raise_on_the_async_client():
    async def check() -> list[str]:
        messages = []
        async with actopo.AsyncClient("127.0.0.1:9", retries=False, timeout=1.0) as client:
            info = _Offline.info()
            session = actopo.AsyncSession(client, info)
            calls = [lambda: client.open_session("mesh-x", structure="fancy"),
                     lambda: session.query("vv", 0),
                     lambda: session.submit("reeb-graph")]
            for call in calls:
                with pytest.raises(actopo.InvalidArgumentError) as e:
                    await call()
                messages.append(str(e.value))
            with pytest.raises(actopo.InvalidArgumentError) as e:
                async for _ in session.relations_stream("vertex_stars", [0]):
                    pass
            messages.append(str(e.value))
        return messages

    messages = asyncio.run(check())
    for message, (parameter, value) in zip(messages, [("structure", "fancy"),
                                                      ("relation", "vv"),
                                                      ("algorithm", "reeb-graph"),
                                                      ("relation", "vertex_stars")],
                                           strict=True):
        assert f"{parameter}: unknown {parameter} '{value}'; available: " in message


def test_names_are_taken_with_either_separator_and_any_case():
    request = _messages.build_open_session("m", None, "Compact", 0, 0, 0.0, "ADAPTIVE",
                                           "declared")
    assert request.structure == pb.STRUCTURE_COMPACT
    assert request.engine.prefetch == pb.PREFETCH_ADAPTIVE
    request, name = _messages.build_run_job("s", "morse_smale", None, False)
    assert request.algorithm == pb.ALGORITHM_MORSE_SMALE and name == "morse-smale"
    assert _requests.relation("Vertex-Edges") == pb.RELATION_VERTEX_EDGES


_KINDS = {(False, False): "UnaryUnary", (False, True): "UnaryStream",
          (True, False): "StreamUnary", (True, True): "StreamStream"}


@pytest.mark.parametrize("protocol,module", [(_stub.Stub, "grpc"),
                                             (_stub.AsyncStub, "grpc.aio")])
def test_the_typed_stubs_are_the_service(protocol, module):
    """actopo._stub types each RPC by hand: the same methods as the proto's service, each with
    its streaming kind, request and response type; the generated stub has each of them."""
    service = pb.DESCRIPTOR.services_by_name["TopologyService"]
    expected = {m.name: f"{module}.{_KINDS[m.client_streaming, m.server_streaming]}"
                        f"MultiCallable[pb.{m.input_type.name}, pb.{m.output_type.name}]"
                for m in service.methods}
    assert dict(protocol.__annotations__) == expected
    for m in service.methods:
        assert getattr(pb, m.input_type.name).DESCRIPTOR is m.input_type
        assert getattr(pb, m.output_type.name).DESCRIPTOR is m.output_type
    with grpc.insecure_channel("127.0.0.1:9") as channel:  # never connected
        generated = pb_grpc.TopologyServiceStub(channel)
        assert all(callable(getattr(generated, name)) for name in expected)


def _modules() -> dict[str, Path]:
    """The package's hand-written modules by dotted name (the generated stubs left out)."""
    found = {"actopo" if path.stem == "__init__" else f"actopo.{path.stem}": path
             for path in PACKAGE.glob("*.py")}
    found["actopo._proto"] = PACKAGE / "_proto" / "__init__.py"
    return found


def _imports(path: Path, name: str, known: set[str]) -> set[str]:
    """The package's modules that the module imports anywhere in it: at the top, inside
    functions and under TYPE_CHECKING alike."""
    package = name if path.stem == "__init__" else name.rsplit(".", 1)[0]

    def nearest(dotted: str) -> str | None:
        while dotted and dotted not in known:
            dotted = dotted.rpartition(".")[0]
        return dotted or None

    targets: set[str | None] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets.update(nearest(alias.name) for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                parts = parts[:len(parts) - node.level + 1]
                base = ".".join([*parts, base] if base else parts)
            for alias in node.names:
                submodule = f"{base}.{alias.name}"
                targets.add(submodule if submodule in known else nearest(base))
    return {t for t in targets if t is not None and t != name}


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """A cycle of the graph as a path [a, b, ..., a], or None."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return [*path[path.index(nxt):], nxt]
            if nxt not in state:
                found = visit(nxt)
                if found:
                    return found
        path.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state:
            found = visit(node)
            if found:
                return found
    return None


def test_module_imports_form_no_cycle():
    modules = _modules()
    graph = {name: _imports(path, name, set(modules)) for name, path in modules.items()}
    assert "actopo._vtk" in graph["actopo._results"]  # results -> files, not back
    assert _cycle(graph) is None, " -> ".join(_cycle(graph) or [])


def test_cycle_finder_sees_cycles():
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b"}, "b": set(), "c": {"a", "b"}}) is None


def test_each_module_imports_first():
    """Each module imported before any other module of the package, as a program that starts
    with it would: a cycle at import time fails here even where the graph above has none."""
    names = sorted(n for n in _modules() if n != "actopo.__main__")
    script = (
        "import importlib, sys\n"
        f"for name in {names!r}:\n"
        "    for loaded in [m for m in sys.modules if m.split('.')[0] == 'actopo'\n"
        "                   and not m.startswith('actopo._proto.actopo')]:\n"
        "        del sys.modules[loaded]\n"
        "    importlib.import_module(name)\n"
        "print('imported', len(" + repr(names) + "))\n")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=120, cwd=PACKAGE.parent)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == f"imported {len(names)}"


def test_ratios_over_nothing_are_one():
    """A ratio over no events is 1.0 (nothing asked for was missed), as the README says."""
    assert actopo.types.EngineStats().hit_rate == 1.0
    assert actopo.types.EngineStats(requests=4, hits=3, misses=1).hit_rate == 0.75
    # Every ratio property of the data types, on the type's all-zero value.
    checked = 0
    for name in actopo.types.__all__:
        cls = getattr(actopo.types, name)
        if not hasattr(cls, "__dataclass_fields__"):
            continue
        if any(f.default is MISSING and f.default_factory is MISSING for f in fields(cls)):
            continue  # a field without a default: no all-zero value
        for attribute, value in vars(cls).items():
            if isinstance(value, property) and attribute.endswith(("_rate", "_ratio")):
                assert getattr(cls(), attribute) == 1.0, f"{name}.{attribute}"
                checked += 1
    assert checked >= 1
