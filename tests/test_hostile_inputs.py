"""Issue 35: every input bounded, every message true. Each hostile input gets one line, exit status 2, no traceback
and nothing left behind; where the input is large, its work is bounded (counted, or a CPU-time limit in a child)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from livox_viz.cli import main
from tests.conftest import SEED_JSON

BOX = {"type": "box", "center": [5, 0, 0], "size": [1, 1, 1]}


def scene(path: Path, *objects: dict, **fields: object) -> None:
    """A scene JSON of ``objects`` (default one box) and any top-level ``fields``."""
    path.write_text(json.dumps({**fields, "objects": list(objects) or [BOX]}))


def write_inputs(folder: Path) -> None:
    """The hostile files the table below names."""
    scene(folder / "pose_null.json", vehicle_pose=None)
    scene(folder / "pose_five.json", vehicle_pose=5)
    scene(folder / "pose_far.json", vehicle_pose=[0, 0, -1e300, 0, 0, 0])
    scene(folder / "pose_text.json", vehicle_pose=[0, 0, -1, 0, 0, "up"])
    scene(folder / "tiny_sphere.json", {"type": "sphere", "center": [5, 0, 0], "radius": 1e-300})
    scene(folder / "huge_sphere.json", {"type": "sphere", "center": [5, 0, 0], "radius": 1e300})
    scene(folder / "tall_post.json", {"type": "cylinder", "center": [5, 0, 0], "radius": 0.1, "height": 1e308})
    scene(folder / "flat_box.json", {**BOX, "size": [1, 1e-300, 1]})
    scene(folder / "fine_terrain.json", {"type": "terrain", "center": [5, 0, 0], "size": [9, 9], "wavelength": 1e-300})
    (folder / "huge.tum").write_text("0 0 1e300 -1 0 0 0 1\n1 0 0 -1 0 0 0 1\n2 0 0 -1 0 0 0 1\n")
    (folder / "far.tum").write_text("".join(f"{t} {150_000 + t} 0 -2 0 0 0 1\n" for t in range(3)))
    (folder / "long_sigma.json").write_text(json.dumps(
        {**SEED_JSON, "LivoxVizReturns": {"range_sigma_m": [[20, 0.02]] * 100_000}}))
    scene(folder / "long_material.json", {**BOX, "material": "x" * 2_000_000})


#: (argv, what the one line must say).
HOSTILE: list[tuple[list[str], str]] = [
    # 1: a scene's vehicle pose that is not six numbers
    (["scan", "--scene", "pose_null.json", "--seconds", "0.1", "--out", "s.ply"],
     r"pose_null.json: 'vehicle_pose' = None: allowed: x, y, z \(m, NED"),
    (["scan", "--scene", "pose_five.json", "--seconds", "0.1", "--out", "s.ply"], r"'vehicle_pose' = 5: allowed"),
    (["render", "--scene", "pose_null.json", "--seconds", "0.1", "--out", "s.png"], r"'vehicle_pose' = None"),
    (["gui", "--scene", "pose_five.json", "--seconds", "0.1"], r"'vehicle_pose' = 5"),
    (["publish", "--scene", "pose_null.json", "--seconds", "0.1", "--to", "127.0.0.1:9"], r"'vehicle_pose' = None"),
    (["scan", "--scene", "pose_far.json", "--seconds", "0.1", "--out", "s.ply"], r"a position beyond 1e\+07 m"),
    (["scan", "--scene", "pose_text.json", "--seconds", "0.1", "--out", "s.ply"], r"'up'\]: allowed"),
    # 5: every pose bounded as --pose is, and the sensor kept within the scene's 100 km span
    (["publish", "--trajectory", "huge.tum", "--seconds", "0.5", "--to", "127.0.0.1:9"],
     r"trajectory huge.tum: pose 1 \(t = 0 s\) is at 0, 1e\+300, -1 m; allowed: \|x\|, \|y\|, \|z\| <= 1e\+07 m"),
    (["scan", "--trajectory", "huge.tum", "--seconds", "0.5", "--out", "s.las"], r"is at 0, 1e\+300, -1 m"),
    (["scan", "--trajectory", "far.tum", "--seconds", "0.5", "--out", "s.las"],
     r"trajectory far.tum takes the sensor to 1.5e\+05, 0, -2 m, and with the scene it spans 1.501e\+05 m; allowed"),
    (["scan", "--pose=200000,0,-2,0,0,0", "--seconds", "0.1", "--out", "s.ply"], r"the vehicle's pose takes the sen"),
    (["render", "--pose=200000,0,-2,0,0,0", "--seconds", "0.1", "--out", "s.png"], r"the vehicle's pose takes the"),
    # 7: sizes a float cannot make triangles of
    (["scan", "--scene", "tiny_sphere.json", "--seconds", "0.1", "--out", "s.ply"],
     r"object 0 \(sphere\): 'radius' = 1e-300; allowed: a number from 0.001 to 100000 m"),
    (["scan", "--scene", "huge_sphere.json", "--seconds", "0.1", "--out", "s.ply"], r"'radius' = 1e\+300; allowed"),
    (["scan", "--scene", "tall_post.json", "--seconds", "0.1", "--out", "s.ply"], r"'height' = 1e\+308; allowed"),
    (["scan", "--scene", "flat_box.json", "--seconds", "0.1", "--out", "s.ply"], r"allowed: 3 numbers from 0.001"),
    (["scan", "--scene", "fine_terrain.json", "--seconds", "0.1", "--out", "s.ply"], r"'wavelength' = 1e-300"),
    # 6: a long value is quoted in part, with its length
    (["info", "--config", "long_sigma.json"], r"\[20, 0.02\], \.\.\.\) \(100,000 items\); allowed: 1 to 16 pairs"),
    (["scan", "--scene", "long_material.json", "--seconds", "0.1", "--out", "s.ply"],
     r"unknown material 'x{80}'\.\.\. \(2,000,000 characters\); allowed"),
    (["scan", "--pose", "1," * 60_000 + "1", "--seconds", "0.1", "--out", "s.ply"], r"\(120,001 characters\)"),
    (["scan", "--returns", "d" * 100_000, "--seconds", "0.1", "--out", "s.ply"], r"characters left out"),
]


@pytest.fixture
def inputs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    write_inputs(tmp_path)
    return tmp_path


def assert_one_line_error(folder: Path, argv: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> str:
    """Run ``livox-viz argv`` in ``folder``: exit 2, one short ``error:`` line matching ``message``, no traceback,
    no file made or removed; returns the line."""
    before = sorted(p.name for p in folder.iterdir())
    code = main(argv)
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if not line.startswith(("publishing", "livox-viz: no display"))]
    assert code == 2, err[:2000]
    assert len(lines) == 1 and "Traceback" not in err, err[:2000]
    assert re.match(r"livox-viz( [a-z]+)?: error: ", lines[0]), lines[0][:2000]
    assert len(lines[0]) < 1000, lines[0][:2000]
    assert re.search(message, lines[0]), lines[0]
    assert sorted(p.name for p in folder.iterdir()) == before
    return lines[0]


@pytest.mark.parametrize(("argv", "message"), HOSTILE, ids=[" ".join(a)[:60] for a, _ in HOSTILE])
def test_a_hostile_input_is_one_short_line_and_exit_2(inputs: Path, capsys: pytest.CaptureFixture[str],
                                                     argv: list[str], message: str) -> None:
    assert_one_line_error(inputs, argv, message, capsys)
