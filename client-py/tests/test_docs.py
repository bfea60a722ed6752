"""The examples of the docstrings and of README.md run and print what they say."""

from __future__ import annotations

import doctest
import re
from pathlib import Path

import numpy as np
from harness import DATA_DIR

from actopo import _client

README = Path(__file__).resolve().parents[1] / "README.md"
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
    assert len(blocks) == 8
    monkeypatch.setenv("ACTOPO_SERVER", server)
    monkeypatch.chdir(README.parents[1])
    for code in blocks:
        exec(compile(code.replace("../shared/data", str(DATA_DIR)), str(README), "exec"), {})
    out = capsys.readouterr().out
    assert "14570 60948 ['eigenfunction4', 'height']" in out
    assert "found cell types: 36290 triangle; hint:" in out
    assert "True\n1 ids[1]: vertex id 1000000000 is outside [0, 8000)\nTrue\nTrue\n" in out
    assert "['read', 'partition', 'encode'] 355914\nstopped in partition\n" in out
    assert ("655 {'0': 245, '0_infinite': 1, '1': 330, '2': 79}\nTrue\n"
            "141 {'0': 63, '0_infinite': 1, '1': 61, '2': 16}\n0 0 6408 False\n") in out
    assert ("SimplifiedField('height', 14570 vertices) 3.6677284240722656 7\nTrue\n"
            "2539 2539\n[3, 8, 2, 0] True\n") in out
    assert ("[('velocityMag', None), ('velocityMag_03', 3.0), ('velocityMag_04', 4.0), "
            "('velocityMag_05', 5.0)]\n[('velocityMag', 655), ('velocityMag_03', 814), "
            "('velocityMag_04', 1008), ('velocityMag_05', 1183)]\n"
            "['velocityMag_02', 'velocityMag_03'] 13.526 [0 0 0 0 1 1 1 1 2 2 2 2]\n"
            "velocityMag_02 161\nvelocityMag_48 818\n") in out
