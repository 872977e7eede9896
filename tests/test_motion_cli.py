"""The motion options on the command line: each misuse a one-line error, the summary in words, TUM input bounded."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from livox_viz import LivoxVizError
from livox_viz.cli import main
from livox_viz.motion import tum
from livox_viz.motion.tum import save_tum

from .test_motion import sharp_turns

MISUSES: list[tuple[list[str], str]] = [
    (["scan", "--seconds", "0.1", "--imu-rate", "400", "--out", "c.npz"], "--imu-rate without --rosbag"),
    (["scan", "--seconds", "0.1", "--imu-noise", "0,0,0,0", "--out", "c.npz"], "--imu-noise without --rosbag"),
    (["scan", "--seconds", "0.1", "--imu-frame", "lidar", "--out", "c.npz"], "--imu-frame without --rosbag"),
    (["scan", "--seconds", "0.1", "--trajectory-speed", "3", "--out", "c.npz"], "--trajectory-speed without "
                                                                                "--trajectory"),
    (["scan", "--seconds", "0.1", "--trajectory", "turns.txt", "--trajectory-speed", "3", "--out", "c.npz"],
     "--trajectory-speed with a TUM file"),
    (["scan", "--seconds", "0.1", "--trajectory", "turns.txt", "--pose=1,2,-3,0,0,0", "--out", "c.npz"],
     "--pose with a TUM file"),
    (["publish", "--seconds", "0.1", "--trajectory", "turns.txt", "--pose=1,2,-3,0,0,0", "--to", "127.0.0.1:9"],
     "--pose with a TUM file"),
    (["scan", "--seconds", "0.1", "--trajectory", "hover", "--trajectory-speed", "5", "--out", "c.npz"],
     "--trajectory-speed with hover"),
    (["scan", "--seconds", "0.1", "--trajectory", "spiral", "--out", "c.npz"],
     "allowed: a TUM file or a built-in flight: hover, line, circle, figure8"),
    (["scan", "--seconds", "0.1", "--imu-noise", "1e308,0,0,0", "--rosbag", "bag"], "allowed: 0 to 1"),
    (["scan", "--seconds", "0.1", "--imu-noise", "0,0,0,inf", "--rosbag", "bag"], "allowed: 0 to 10"),
    (["scan", "--seconds", "0.1", "--imu-rate", "1e9", "--rosbag", "bag"], "allowed: 200 to 10000 Hz"),
    (["scan", "--seconds", "0.1", "--trajectory", "line", "--trajectory-speed", "1e9", "--out", "c.npz"],
     "allowed: 0 to 100 m/s"),
    (["scan", "--seconds", "0.1", "--trajectory", "long_line.txt", "--out", "c.npz"], "line 3 is longer than 1000"),
    (["scan", "--seconds", "20", "--trajectory", "turns.txt", "--out", "c.npz"], "no extrapolation"),
]


@pytest.fixture
def inputs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.chdir(tmp_path)
    save_tum(sharp_turns(), tmp_path / "turns.txt")
    (tmp_path / "long_line.txt").write_text("0 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n" + "2" * 5000 + "\n")
    return tmp_path


@pytest.mark.parametrize(("argv", "message"), MISUSES, ids=[" ".join(a)[:70] for a, _ in MISUSES])
def test_a_motion_option_misused_is_a_one_line_error(inputs: Path, capsys: pytest.CaptureFixture[str],
                                                     argv: list[str], message: str) -> None:
    before = sorted(p.name for p in inputs.iterdir())
    code = main(argv)
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if not line.startswith("publishing")]
    assert code == 2, err
    assert len(lines) == 1 and re.match(r"livox-viz( [a-z]+)?: error: ", lines[0]), err
    assert message in lines[0], lines[0]
    assert sorted(p.name for p in inputs.iterdir()) == before


@pytest.mark.parametrize(("argv", "words"), [
    (["--trajectory", "hover"], "not moving (hovering)"),
    (["--trajectory", "line", "--trajectory-speed", "0"], "not moving (hovering)"),
    (["--trajectory", "circle", "--trajectory-speed", "4"], "moving along circle at 4 m/s"),
])
def test_the_summary_says_whether_the_sensor_moves(inputs: Path, capsys: pytest.CaptureFixture[str],
                                                   argv: list[str], words: str) -> None:
    assert main(["scan", "--seconds", "0.2", "--out", "c.npz", *argv]) == 0
    out = capsys.readouterr().out
    assert words in out and "moving along hover" not in out


def test_a_tum_file_is_read_only_as_far_as_the_scan_needs(inputs: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A long file whose far end is garbage: a short scan never reads it; the whole file is refused where it breaks."""
    t = np.arange(0.0, 2000.0, 0.01)
    rows = np.column_stack([t, t, np.zeros((t.size, 5)), np.ones(t.size)])
    with open("long.txt", "w") as handle:
        np.savetxt(handle, rows, fmt="%.6f")
        handle.write("not a pose at all\n")
    assert main(["scan", "--seconds", "0.3", "--trajectory", "long.txt", "--out", "c.npz"]) == 0
    loaded = tum.load_tum("long.txt", 0.0, 0.3)
    assert loaded.t.size == 31 + 2 * tum.MARGIN_POSES - tum.MARGIN_POSES  # no poses before 0: only after
    with pytest.raises(LivoxVizError, match=f"line {t.size + 1} has 5 values"):
        tum.load_tum("long.txt")
    # Reading a window in the middle gives the whole file's spline there.
    middle = tum.load_tum("long.txt", 500.0, 501.0)
    assert middle.t[0] < 500.0 and middle.t[-1] > 501.0 and middle.t.size == 101 + 2 * tum.MARGIN_POSES
    clean = tum.load_tum("long.txt", 0.0, 1500.0)
    query = np.linspace(500.0, 501.0, 777)
    np.testing.assert_allclose(middle.poses_at(query)[0], clean.poses_at(query)[0], atol=1e-12)


def test_a_tum_file_past_the_pose_limit_is_refused(inputs: Path, monkeypatch: pytest.MonkeyPatch,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(tum, "MAX_POSES", 5)
    assert main(["scan", "--seconds", "10", "--trajectory", "turns.txt", "--out", "c.npz"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "more than 5 poses in the scan's span; allowed: at most 5" in err


def test_publish_along_a_tum_file_runs_to_its_end_without_seconds(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """No --seconds: a TUM trajectory sets the length (0.5 s: five frames), not the 10 s default it cannot cover."""
    tum = tmp_path / "short.txt"
    tum.write_text("0 0 0 -2 0 0 0 1\n0.25 1 0 -2 0 0 0 1\n0.5 2 0 -2 0 0 0 1\n")
    assert main(["publish", "--trajectory", str(tum), "--to", "127.0.0.1:9", "--unpaced"]) == 0
    captured = capsys.readouterr()
    assert "to the trajectory's end at 0.5 s" in captured.err and "sent 5 frames" in captured.out
    assert main(["publish", "--trajectory", str(tum), "--to", "127.0.0.1:9", "--unpaced", "--seconds", "2"]) == 2
    assert "spans 0 to 0.5 s" in capsys.readouterr().err
