"""A real sensor's saved frame (PCD, PLY, a CSV of x, y, z) as the reference of ``compare`` and ``load_reference``.

The frames are made from the Tele-15's own track (:mod:`tests.made_frames`), so
the reference's rows must land on the preset's samples of the same firings, a
no-return row being a gap.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import livox_viz.files  # noqa: F401  (registers the recording readers, as the command line and the window do)
from livox_viz import load_preset
from livox_viz.cli import main
from livox_viz.fitting.compare import compare
from livox_viz.fitting.reference import is_point_csv, load_reference
from livox_viz.patterns.factory import make_pattern
from tests.made_frames import HEAD, made_frame, write_pcd, write_xyz_csv

RATE = 240_000.0


@pytest.fixture(scope="module")
def frame() -> np.ndarray:
    return made_frame(0.1)


@pytest.mark.parametrize(("suffix", "form"), [(".pcd", "PCD"), (".csv", "CSV")])
def test_a_frames_returns_are_its_rows_at_their_own_firings(tmp_path: Path, frame: np.ndarray, suffix: str,
                                                            form: str) -> None:
    path = tmp_path / f"frame{suffix}"
    (write_pcd if suffix == ".pcd" else write_xyz_csv)(path, frame)
    table = load_reference(path, recording_rate=RATE)
    returned = np.flatnonzero(frame.any(axis=1))
    assert table.recording == form and table.rate == RATE and "no per-point times" in table.rate_source
    np.testing.assert_array_equal(table.slots, returned)
    ours = make_pattern(load_preset(HEAD)).take(frame.shape[0]).xy_deg
    assert np.abs(table.xy_deg - ours[returned]).max() < 1e-3


def test_a_csv_is_a_recording_by_its_header_and_its_own_times_give_the_rate(tmp_path: Path,
                                                                            frame: np.ndarray) -> None:
    path = write_xyz_csv(tmp_path / "timed.csv", frame, np.arange(frame.shape[0]) / RATE)
    livox = tmp_path / "livox.csv"
    livox.write_text("Time/s,Azimuth/deg,Zenith/deg\n0,1,89\n", encoding="utf-8")
    assert is_point_csv(path) and not is_point_csv(livox)
    table = load_reference(path)  # no rate given: the t column's
    assert table.rate == RATE and table.rate_source == "its time column"
    np.testing.assert_array_equal(table.slots, np.flatnonzero(frame.any(axis=1)))


def test_compare_holds_a_frame_to_its_preset_over_its_span(tmp_path: Path, frame: np.ndarray,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    path = write_pcd(tmp_path / "frame.pcd", frame)
    result = compare(load_preset(HEAD), load_reference(path, recording_rate=RATE))
    np.testing.assert_array_equal(result.seconds, [0.05, 0.1])
    # A quarter of the firings returned nothing; the rest cover the FOV as the preset's every firing does.
    np.testing.assert_allclose(result.coverage_reference, result.coverage_ours, atol=0.02)
    assert result.track_residual is not None and result.track_residual[0] < 1e-3
    assert main(["compare", "--preset", HEAD, str(path)]) == 0
    out = capsys.readouterr().out
    assert "the PCD recording's" in out and "no-returns" in out and "align a twin" not in out


def test_compare_says_how_to_align_a_recording_whose_phases_are_not_the_presets(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_xyz_csv(tmp_path / "later.csv", made_frame(0.05, first_sample=7777))
    assert main(["compare", "--preset", HEAD, str(path)]) == 0
    out = capsys.readouterr().out
    assert f"livox-viz fit {path} --preset {HEAD} --out twin.json" in out


@pytest.mark.parametrize(("name", "said"), [
    ("folder", "is a folder"),
    ("nox.pcd", "its fields are a, y, z; allowed: fields x, y and z"),
    ("zero.csv", "no returns in its 40 rows"),
])
def test_a_bad_recording_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str,
                                     said: str) -> None:
    (tmp_path / "folder").mkdir()
    (tmp_path / "nox.pcd").write_text("FIELDS a y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nPOINTS 20\nDATA ascii\n"
                                      + "1 2 3\n" * 20, encoding="ascii")
    write_xyz_csv(tmp_path / "zero.csv", np.zeros((40, 3)))
    assert main(["compare", "--preset", HEAD, str(tmp_path / name)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and said in err and "Traceback" not in err, err
