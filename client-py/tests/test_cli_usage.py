"""The `actopo` command line as a new user meets it (issue 54), each command run in a process of
its own as the README writes it: the defaults its help states are the server's, a usage error
exits 2 naming the flag, a service error 1, a closed stdout ends it quietly, and the names of
meshes and samples get answers that say what to type instead."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys

import pytest
from harness import run_cli

from actopo._cli_parser import SERVER_DEFAULTS


def _help_default(text: str, flag: str) -> str:
    """What `--help` says a flag's default is: the X of "(default: the server's, X)" in the
    flag's own lines (after "options:", not in the usage)."""
    words = " ".join(text.split("\noptions:\n", 1)[1].split())
    found = re.search(rf"{flag} \S+ (?:(?!--).)*?\(default: the server's, ([^)]*)\)", words)
    assert found, f"{flag}: no default in the help:\n{text}"
    return found.group(1)


def _meaning(default: str, cores: int) -> float:
    """A default as the help says it, as a number on this machine (the server's)."""
    return {"one per server core": cores,
            "one per server core, at most 4": min(cores, 4)}.get(default) or float(default)


def test_help_states_the_defaults_the_server_uses(server):
    """`run`, `open` and `relation --help` quote SERVER_DEFAULTS; a session opened without the
    flags (the CLI sends 0 for each) and a mesh loaded without --block-size have those values.
    The server runs here, so its cores are this machine's."""
    mesh = json.loads(run_cli(server, "load", "sample:jittered:6", "--json").stdout)
    try:
        opened = run_cli(server, "open", mesh["mesh_id"], "--json")
        assert opened.returncode == 0, opened.stderr
        engine = json.loads(opened.stdout)["engine"]
        assert run_cli(server, "close", json.loads(opened.stdout)["session_id"]).returncode == 0
    finally:
        run_cli(server, "delete", mesh["mesh_id"])
    cores = os.cpu_count() or 1
    real = {"--consumers": engine["consumers"], "--producers": engine["producers"],
            "--buffer-ratio": engine["buffer_ratio"], "--query-readers": engine["query_readers"],
            "--block-size": mesh["block_size"]}
    assert real["--consumers"] == cores and real["--producers"] == 1
    for command in ("run", "open", "relation"):
        text = run_cli(server, command, "--help").stdout
        for flag, value in real.items():
            if flag == "--block-size" and command == "open":
                continue  # open takes a loaded mesh
            said = _help_default(text, flag)
            assert said == SERVER_DEFAULTS[flag], (command, flag)
            assert _meaning(said, cores) == pytest.approx(value), (command, flag, said, value)


@pytest.mark.parametrize("args,message", [
    (["run", "critical-points", "--sample", "jittered:4", "--param", "embedding"],
     "argument --param: 'embedding' is not NAME=VALUE (e.g. --param embedding=domain)"),
    (["run", "critical-points", "--sample", "jittered:4", "--param", "=domain"],
     "argument --param: '=domain' is not NAME=VALUE"),
    (["run", "critical-points", "--sample", "jittered:4", "--block-size", "-5"],
     "argument --block-size: -5 is outside [0, 2147483647] (0: the server's default)"),
    (["load", "sample:jittered:4", "--block-size", "-5"],
     "argument --block-size: -5 is outside [0, 2147483647]"),
    (["run", "critical-points", "--sample", "jittered:4", "--consumers", "-1"],
     "argument --consumers: -1 is outside [0, 64] (0: the server's default)"),
    (["open", "mesh-1", "--producers", "65"], "argument --producers: 65 is outside [0, 64]"),
    (["relation", "vertex_star", "0", "--sample", "jittered:4", "--query-readers", "x"],
     "argument --query-readers: not an integer: 'x'"),
    (["run", "critical-points", "--sample", "jittered:4", "--buffer-ratio", "1.5"],
     "argument --buffer-ratio: 1.5 is outside [0, 1]"),
    (["run", "persistence-diagram", "--sample", "jittered:4", "--plot", "d.png",
      "--threshold", "-1%"], "argument --threshold: must be a number >= 0, got -1%"),
    (["run", "persistence-diagram", "--sample", "jittered:4", "--plot", "d.png",
      "--threshold", "-0.5"], "argument --threshold: must be a number >= 0, got -0.5"),
    (["compare", "--sample", "jittered:4", "--algorithm", "critical-points", "--repeat", "0"],
     "argument --repeat: must be positive, got 0"),
    (["run", "critical-points", "--sample", "jittered:4", "--threshold", "1%"],
     "--threshold is the line of the plot: give --plot PATH.png too"),
])
def test_usage_errors_exit_2_naming_the_flag(server, args, message):
    done = run_cli(server, *args)
    assert (done.returncode, done.stdout) == (2, ""), done.stderr
    assert message in done.stderr and "Traceback" not in done.stderr


def test_service_errors_exit_1(server):
    done = run_cli(server, "load", "no_such_file.vtu")
    assert done.returncode == 1 and done.stderr == (
        "actopo: error: path: 'no_such_file.vtu' not found in the data directory [NOT_FOUND]\n")
    done = run_cli(server, "relation", "edge_triangles", "0,63", "--sample", "jittered:4")
    assert done.returncode == 1 and "(0, 63) is not a" in done.stderr and "NOT_FOUND" in done.stderr


@pytest.mark.parametrize("args", [["info"], ["stats", "--json"], ["meshes"]])
def test_a_closed_stdout_ends_the_command_quietly(server, args):
    """`actopo stats --json | head -1`: when the reader of stdout is gone, the command ends with
    141 (a program SIGPIPE stopped) and says nothing: no "Broken pipe", no traceback."""
    process = subprocess.Popen([sys.executable, "-m", "actopo", *args], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True,
                               env={**os.environ, "ACTOPO_SERVER": server})
    process.stdout.close()  # as `head` does once it has its line, here before the first
    _, err = process.communicate(timeout=60)
    assert (process.returncode, err) == (141, "")


@pytest.mark.parametrize("args,hint", [
    (["run", "critical-points", "--mesh", "wavelet:16"], "did you mean sample:wavelet:16?"),
    (["load", "wavelet"], "did you mean sample:wavelet?"),
    (["relation", "vertex_star", "0", "--mesh", "jittered:4"], "did you mean sample:jittered:4?"),
    (["load", "fertility"], "a mesh file has an extension (.vtu, .vtk, .vti, .pvd), and a "
     "built-in sample is sample:NAME, of wavelet:N, jittered:N"),
])
def test_a_mesh_name_that_is_a_sample_says_how_to_write_it(server, args, hint):
    done = run_cli(server, *args)
    assert done.returncode == 1 and hint in done.stderr, done.stderr
    assert "not found in the data directory" in done.stderr and "[NOT_FOUND]" in done.stderr


def test_samples_by_name_with_or_without_sample_prefix(server):
    runs = [run_cli(server, "run", "critical-points", "--sample", name, "--json")
            for name in ("jittered:4", "sample:jittered:4")]
    assert [r.returncode for r in runs] == [0, 0], runs[1].stderr
    assert [json.loads(r.stdout)["mesh"]["source"] for r in runs] == ["sample:jittered:4"] * 2
    done = run_cli(server, "run", "critical-points", "--sample", "nope:3")
    assert done.returncode == 1 and done.stderr == (
        "actopo: error: sample 'nope:3': unknown sample; samples: wavelet:N, jittered:N "
        "(`actopo info` describes them) [INVALID_ARGUMENT]\n")
    done = run_cli(server, "load", "sample:wavelet:1")
    assert done.returncode == 1 and done.stderr == (
        "actopo: error: sample 'wavelet:1': N = 1 is outside [2, 512]; samples: wavelet:N, "
        "jittered:N (`actopo info` describes them) [INVALID_ARGUMENT]\n")


def test_uploading_a_file_that_is_no_mesh_names_it_and_the_formats(server, tmp_path):
    notes = tmp_path / "notes.txt"
    notes.write_text("not a mesh\n")
    for args in (["upload", str(notes)], ["run", "critical-points", "--upload", str(notes)]):
        done = run_cli(server, *args)
        assert done.returncode == 1 and done.stderr == (
            f"actopo: error: {notes}: not a mesh file that pyvista or meshio reads; give a "
            "tetrahedral mesh in a file VTK writes (.vtu, a legacy .vtk unstructured grid) or "
            "one meshio reads (e.g. .msh, .mesh, .inp, .xdmf)\n")


def test_run_creates_the_directories_of_its_files(server, tmp_path):
    done = run_cli(server, "run", "persistence-diagram", "--sample", "jittered:5", "--output",
                   "out/a/d", "--plot", "plots/d.png", "--trace", "traces/job.json",
                   cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    for path in ("out/a/d_diagram.vtu", "plots/d.png", "traces/job.json"):
        assert (tmp_path / path).is_file() and f"wrote {path}" in done.stdout
