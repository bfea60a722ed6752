"""The examples of the docstrings and of README.md run and print what they say, and the `actopo`
commands of README.md and ../README.md run and show what they say."""

from __future__ import annotations

import doctest
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import meshio
import numpy as np
import pytest
from harness import DATA_DIR, run_cli

from actopo import _client

README = Path(__file__).resolve().parents[1] / "README.md"
TOP_README = README.parents[1] / "README.md"
POINTS = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], dtype=float)
TETRAHEDRA = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])


def test_docstring_examples(client):
    height = POINTS[:, 2] + 0.1 * POINTS[:, 0]
    mesh = client.upload_mesh((POINTS, TETRAHEDRA, {"height": height}), name="two tets")
    try:
        with client.open_session(mesh) as session:
            result = doctest.testmod(_client, extraglobs={"client": client, "session": session},
                                     optionflags=doctest.NORMALIZE_WHITESPACE)
    finally:
        client.delete_mesh(mesh)
    assert result.attempted >= 10 and result.failed == 0


def test_readme_examples(server, monkeypatch, capsys):
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    assert len(blocks) == 11
    monkeypatch.setenv("ACTOPO_SERVER", server)
    monkeypatch.chdir(README.parents[1])
    for code in blocks:
        exec(compile(code.replace("../shared/data", str(DATA_DIR)), str(README), "exec"), {})
    out = capsys.readouterr().out
    assert "14570 60948 ['eigenfunction4', 'height']" in out
    assert "found cell types: 36290 triangle; hint:" in out
    assert ("isabel_series_s2_tet.vtu upload:isabel_series_s2_tet.vtu 230640\n"
            "True ['send', 'read', 'partition', 'encode']\n"
            "[('velocityMag_0', 2.0), ('velocityMag_1', 3.0), ('velocityMag_2', 4.0), "
            "('velocityMag_3', 5.0)]\n") in out
    assert ("MeshArrays('viscousFingers001_s2_tet.vtu', 32768 vertices, 148955 tetrahedra, "
            "fields ['density'])\nint32 float32 148955\n") in out
    assert "True\n1 ids[1]: vertex id 1000000000 is outside [0, 8000)\nTrue\nTrue\n" in out
    assert "['read', 'partition', 'encode'] 355914\nstopped in partition\n" in out
    assert ("655 {'0': 245, '0_infinite': 1, '1': 330, '2': 79}\nTrue\n"
            "141 {'0': 63, '0_infinite': 1, '1': 61, '2': 16}\n0 0 6408 False\n") in out
    assert ("SimplifiedField('height', 14570 vertices) 3.6677284240722656 7\nTrue\n"
            "2539 2539\n[3, 8, 2, 0] True\n") in out
    assert ("Tree('join', 20 nodes, 19 arcs, 1 component) {'0': 10, '1': 9, '3': 1}\nTrue\n"
            "[ 339 2311 1777] [1974 4871 2830]\n10 [ 339 2311 1825] [73.35 20.17  6.79]\n"
            "8273 8275\nTree('split', 26 nodes, 25 arcs, 1 component) "
            "Tree('contour', 6 nodes, 5 arcs, 1 component)\n19 0\n") in out
    assert ("[('velocityMag', None), ('velocityMag_03', 3.0), ('velocityMag_04', 4.0), "
            "('velocityMag_05', 5.0)]\n[('velocityMag', 655), ('velocityMag_03', 814), "
            "('velocityMag_04', 1008), ('velocityMag_05', 1183)]\n"
            "[('velocityMag_0', 2.0), ('velocityMag_1', 3.0), ('velocityMag_2', 4.0), "
            "('velocityMag_3', 5.0)]\n"
            "['velocityMag_02', 'velocityMag_03'] 13.526 [0 0 0 0 1 1 1 1 2 2 2 2]\n"
            "velocityMag_02 161\nvelocityMag_48 818\n") in out


# The `actopo` commands of the READMEs.


def doc_commands(readme: Path) -> list[str]:
    """The `actopo ...` commands of a README in its order, once each, one space between words:
    the lines of its code blocks that start with `actopo ` (continued lines joined, comments
    dropped) and its code spans that do."""
    text = readme.read_text()
    found = []
    for block in re.findall(r"```[a-z]*\n(.*?)```", text, flags=re.S):
        for line in block.replace("\\\n", " ").splitlines():
            line = re.sub(r"\s+#.*$", "", line.strip())
            if line.startswith("actopo "):
                found.append(line)
    for span in re.findall(r"`([^`]+)`", re.sub(r"```.*?```", "", text, flags=re.S)):
        if span.startswith("actopo "):
            found.append(span)
    return list(dict.fromkeys(" ".join(c.split()) for c in found))


@dataclass
class Step:
    """One command run for a README's command: `command` with its placeholders filled in
    ({server}, {mesh}: fertility_tet.vtu loaded, {session}: a session on it, {isabel}:
    isabel_series_s2/isabel_02_s2_tet.vtu loaded), what stdout `shows`, the files it `writes`
    (under the working directory), whether it prints `run --json`'s documented keys, whether
    it is a shell pipeline (run by bash, stderr checked empty), and whether $ACTOPO_DATA_DIR
    names the server's data folder (`local_data`; False: as on a machine without its files, so
    that `run --output` writes the per-vertex files on the geometry it downloads)."""

    command: str
    shows: tuple[str, ...] = ()
    writes: tuple[str, ...] = ()
    json_keys: bool = False
    shell: bool = False
    local_data: bool = True


BENCH_TABLE = ("REQ/S", "P99.9_MS", "SERVER_CALLS")
RUN_FIELDS = ("  velocityMag_02: ", "  velocityMag_48: ")
# Every `actopo` command of the two READMEs: the steps it runs here, or why it runs nowhere.
# bench runs for N requests per client, where the README's runs 5 s per mode.
COMMANDS: dict[str, list[Step] | str] = {
    "actopo info": [Step("actopo info", ("algorithms:", "relations:", "samples:", "limits:"))],
    "actopo meshes | sessions [--json]": [
        Step("actopo meshes", ("MESH  ",)), Step("actopo sessions", ("SESSION  ",)),
        Step("actopo meshes --json", ("[",)), Step("actopo sessions --json", ("[",))],
    "actopo load fertility_tet.vtu": [Step("actopo load fertility_tet.vtu",
                                           ("fertility_tet.vtu", " 60948 "))],
    "actopo load isabel_series_s2/isabel_02_s2_tet.vtu isabel_series_s2/isabel_03_s2_tet.vtu "
    "--times 2,3": [
        Step("actopo load isabel_series_s2/isabel_02_s2_tet.vtu "
             "isabel_series_s2/isabel_03_s2_tet.vtu --times 2,3",
             ("isabel_02_s2_tet.vtu +1 file", "velocityMag_0,velocityMag_1"))],
    "actopo upload ../shared/data/fertility_tet.vtu": [
        Step("actopo upload ../shared/data/fertility_tet.vtu", ("fertility_tet.vtu", " 60948 "))],
    "actopo load my_mesh.vtu": [Step("actopo load my_mesh.vtu", ("my_mesh.vtu", " 24 "))],
    "actopo add-fields MESH_ID steps.vtu --fields velocityMag_03,velocityMag_04 --times 3,4": [
        Step("actopo add-fields {isabel} steps.vtu --fields velocityMag_03,velocityMag_04 "
             "--times 3,4", ("velocityMag_03  ", "velocityMag_04  "))],
    "actopo delete-field MESH_ID velocityMag_04": [
        Step("actopo delete-field {isabel} velocityMag_04", ("velocityMag_03",))],
    "actopo run --mesh fertility_tet.vtu --algorithm morse-smale --structure actopo --json": [
        Step("actopo run --mesh fertility_tet.vtu --algorithm morse-smale --structure actopo "
             "--json", json_keys=True)],
    "actopo run --upload my_mesh.vtu --algorithm critical-points --output out/my": [
        Step("actopo run --upload my_mesh.vtu --algorithm critical-points --output out/my",
             writes=("out/my_critical_points.vtp",))],
    "actopo run persistence-diagram --mesh isabel02_s2_tet.vtu --scalar velocityMag --plot "
    "diagram.png --threshold 1%": [
        Step("actopo run persistence-diagram --mesh isabel02_s2_tet.vtu --scalar velocityMag "
             "--plot diagram.png --threshold 1%", ("wrote diagram.png",), ("diagram.png",))],
    "actopo run topological-simplification --mesh fertility_tet.vtu --scalar height --param "
    "relative_threshold=0.05 --output out/fertility": [
        Step("actopo run topological-simplification --mesh fertility_tet.vtu --scalar height "
             "--param relative_threshold=0.05 --output out/fertility", ('"backend": "lts"',),
             ("out/fertility_simplified.vtu",), local_data=False)],
    "actopo run merge-tree --mesh fertility_tet.vtu --scalar height --tree split --plot "
    "tree.png": [
        Step("actopo run merge-tree --mesh fertility_tet.vtu --scalar height --tree split "
             "--plot tree.png", ('"tree": "split"', "wrote tree.png"), ("tree.png",))],
    "actopo run persistence-diagram --mesh isabel_series_s2_tet.vtu --scalars all": [
        Step("actopo run persistence-diagram --mesh isabel_series_s2_tet.vtu --scalars all",
             RUN_FIELDS)],
    "actopo run diagram-distance --mesh isabel_series_s2_tet.vtu --scalars all --param p=1 "
    "--plot distances.png": [
        Step("actopo run diagram-distance --mesh isabel_series_s2_tet.vtu --scalars all "
             "--param p=1 --plot distances.png", ("Wasserstein-1:", "bottleneck:"),
             ("distances.png",))],
    "actopo relation vertex_star 0 1 2 --mesh sample:jittered:8": [
        Step("actopo relation vertex_star 0 1 2 --mesh sample:jittered:8",
             ("vertex_star(0): ", "vertex_star(1): ", "vertex_star(2): "))],
    "actopo relation edge_triangles 0,1 --vertices --session SESSION_ID": [
        Step("actopo relation edge_triangles 0,1 --vertices --session {session}",
             ("edge_triangles([0, 1]): ",))],
    "actopo open MESH_ID --structure compact": [
        Step("actopo open {mesh} --structure compact", (" compact ",))],
    "actopo stats [--session ID]": [Step("actopo stats", ("SESSION  ",)),
                                    Step("actopo stats --session {session}", ("{session}",))],
    "actopo compare --mesh fertility_tet.vtu --algorithm discrete-gradient --structures "
    "explicit,compact,actopo": [
        Step("actopo compare --mesh fertility_tet.vtu --algorithm discrete-gradient "
             "--structures explicit,compact,actopo", ("SAME_RESULT", "explicit ", "compact ",
                                                      "actopo "))],
    "actopo bench --target HOST:PORT --sample wavelet:30": [
        Step("actopo bench --target {server} --sample wavelet:30 --requests 2", BENCH_TABLE)],
    "actopo stats --json | head -1": [Step("actopo stats --json | head -1", ("{",), shell=True)],
    "actopo close SESSION_ID / actopo delete MESH_ID": [Step("actopo close {session}"),
                                                        Step("actopo delete {mesh}")],
    "actopo bench --target 127.0.0.1:50051 --sample wavelet:40 --structure compact,actopo "
    "--clients 1,4 --duration 5 [--modes unary,batch,stream,job] [--relation vertex_star] "
    "[--order sequential|random] [--requests N] [--query-readers R] [--json]": [
        Step("actopo bench --target {server} --sample wavelet:40 --structure compact,actopo "
             "--clients 1,4 --duration 5 --modes unary,batch,stream,job --relation vertex_star "
             "--order random --requests 2 --query-readers 2 --json", ('"runs": [',))],
    # ../README.md
    "actopo run --mesh isabel_series_s2_tet.vtu diagram-distance --scalars all --plot "
    "docs/isabel_distance_matrix.png": [
        Step("actopo run --mesh isabel_series_s2_tet.vtu diagram-distance --scalars all "
             "--plot docs/isabel_distance_matrix.png", ("Wasserstein-2:",),
             ("docs/isabel_distance_matrix.png",))],
    "actopo bench --server HOST:PORT --sample wavelet:80 --modes unary,batch,stream,job "
    "--clients 1,8": [
        Step("actopo bench --server {server} --sample wavelet:80 --modes unary,batch,stream,job "
             "--clients 1,8 --requests 1", BENCH_TABLE)],
    "actopo --server HOST:PORT run --mesh fertility_tet.vtu --algorithm morse-smale --json": [
        Step("actopo --server {server} run --mesh fertility_tet.vtu --algorithm morse-smale "
             "--json", json_keys=True)],
    # Commands named in a sentence, not given to run: each runs above as a whole command.
    "actopo run --trace FILE": "an option named in prose (test_cli.py writes traces)",
    "actopo load": "a command named in prose",
    "actopo ... --mesh": "an option named in prose",
    "actopo ... --sample": "an option named in prose",
    "actopo run --plot": "an option named in prose",
    "actopo run persistence-diagram --plot": "an option named in prose",
    "actopo run diagram-distance --plot PATH.png": "an option named in prose",
    "actopo stats": "a command named in prose",
    "actopo compare": "a command named in prose",
    "actopo bench": "a command named in prose",
    "actopo run": "a command named in prose",
}


def run_keys() -> tuple[set[str], set[str]]:
    """The keys README.md says `run --json` prints: always, and when it wrote the files."""
    words = " ".join(README.read_text().split())
    sentence = re.search(r"`run --json` prints one object with (.*?) when it wrote them", words)
    assert sentence, "README.md: the sentence on `run --json`'s keys moved"
    always, _, written = sentence.group(1).partition(" plus ")
    return set(re.findall(r"`(\w+)`", always)), set(re.findall(r"`(\w+)`", written))


def test_every_readme_command_is_run_or_says_why_not():
    commands = doc_commands(README) + doc_commands(TOP_README)
    assert not [c for c in commands if c not in COMMANDS], "add them to COMMANDS"
    assert not [c for c in COMMANDS if c not in commands], "no README has them any more"
    always, written = run_keys()
    assert {"mesh", "job_id", "result"} <= always and written == {"files", "plot", "trace"}


@pytest.fixture
def placeholders(client, tmp_path):
    """What the READMEs' placeholders stand for, and the local files their commands name, in
    `tmp_path` (the commands' working directory); every mesh and session the commands leave is
    gone afterwards."""
    meshes = {m.mesh_id for m in client.list_meshes()}
    sessions = {s.session_id for s in client.list_sessions()}
    mesh = client.load_mesh("fertility_tet.vtu")
    isabel = client.load_mesh("isabel_series_s2/isabel_02_s2_tet.vtu")
    session = client.open_session(mesh)
    steps = {f"velocityMag_0{t}": meshio.read(
        DATA_DIR / f"isabel_series_s2/isabel_0{t}_s2_tet.vtu").point_data["velocityMag"]
        for t in (3, 4)}
    grid = meshio.read(DATA_DIR / "isabel_series_s2/isabel_02_s2_tet.vtu")
    meshio.Mesh(grid.points, grid.cells, point_data=steps).write(tmp_path / "steps.vtu")
    shutil.copy(DATA_DIR / "manifoldCheck0_tet.vtu", tmp_path / "my_mesh.vtu")
    yield {"server": client.target, "mesh": mesh.mesh_id, "session": session.session_id,
           "isabel": isabel.mesh_id}
    for s in client.list_sessions():
        if s.session_id not in sessions:
            client.close_session(s.session_id)
    for m in client.list_meshes():
        if m.mesh_id not in meshes:
            client.delete_mesh(m.mesh_id)


@pytest.mark.parametrize("readme", [README, TOP_README], ids=["client-py", "top"])
def test_readme_commands_run_and_show_what_they_say(server, placeholders, tmp_path, readme):
    """Each command in the README's order, as a user types it in a fresh directory beside a
    server on ../shared/data (`../shared/data` in a command is that folder): exit status 0, the
    output and files the README shows, and for `run --json` the keys it lists."""
    always, _ = run_keys()

    def fill(text: str) -> str:
        return re.sub(r"\{(\w+)\}", lambda name: placeholders[name.group(1)], text)

    for text in doc_commands(readme):
        steps = COMMANDS[text]
        if isinstance(steps, str):
            continue
        for step in steps:
            command = fill(step.command).replace("../shared/data", str(DATA_DIR))
            env = {"ACTOPO_DATA_DIR": str(DATA_DIR) if step.local_data else ""}
            if step.shell:
                done = subprocess.run(
                    ["bash", "-c", command.replace("actopo ", f"{sys.executable} -m actopo ")],
                    capture_output=True, text=True, timeout=300, cwd=tmp_path,
                    env={**os.environ, "ACTOPO_SERVER": server, **env})
                assert done.stderr == "", f"{command}: {done.stderr}"
            else:
                done = run_cli(server, *shlex.split(command)[1:], cwd=tmp_path, env=env)
            assert done.returncode == 0, f"{command}: {done.stderr}"
            assert "not written" not in done.stderr, f"{command}: {done.stderr}"
            for shown in step.shows:
                assert fill(shown) in done.stdout, f"{command}: {done.stdout}"
            for path in step.writes:
                assert (tmp_path / path).stat().st_size > 0, f"{command}: no {path}"
            if step.json_keys:
                assert set(json.loads(done.stdout)) == always, command
