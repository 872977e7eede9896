"""A head's track fitted to a recorded frame: known answers from frames we make, refusals, the files users have.

The frames are made here (no test reads the development folder): a preset's track turned
into one of its mirror images, its lasers reversed, started at some laser and
phase, its motors off nominal by a few hundred ppm, with angular noise and
no-returns, written as a real sensor's frame (x forward, y left, z up, rows in
firing order, no-returns as (0, 0, 0)).
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np
import pytest

from livox_viz import load_preset
from livox_viz.cli import main
from livox_viz.core.errors import LivoxVizError
from livox_viz.files.frame_files import read_frame_rows
from livox_viz.fitting.recording_fit import IMAGES, RecordedFrame, fit_recording, imaged_config
from livox_viz.patterns.factory import make_pattern
from livox_viz.patterns.planes import directions_from_xy

SECONDS = 0.03


def angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    a = a / np.linalg.norm(a, axis=1, keepdims=True)
    b = b / np.linalg.norm(b, axis=1, keepdims=True)
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.sum(a * b, axis=1)))


def truth(preset: str, image: str, reverse: bool, ppm: tuple[float, float], phase: tuple[float, float]):
    """The sensor a frame is made from: the preset's track imaged, its motors off and its phases moved."""
    config = imaged_config(load_preset(preset), image, reverse)
    risley = config.risley
    moved = dataclasses.replace(risley, prism_hz=tuple(f * (1 + 1e-6 * p) for f, p in zip(risley.prism_hz, ppm,
                                                                                            strict=True)),
                                phase_rad=tuple(a + b for a, b in zip(risley.phase_rad, phase, strict=True)))
    return dataclasses.replace(config, risley=moved)


def made_frame(config, first_sample: int, seconds: float = SECONDS, noise_deg: float = 0.01,
               no_returns: float = 0.25, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Rows ``(n, 3)`` in the Livox frame (x forward, y left, z up), no-returns zero; and the true FRD rays."""
    rng = np.random.default_rng(seed)
    count = round(seconds * config.point_rate)
    xy = make_pattern(config).points(first_sample, count).xy_deg.copy()
    rays = directions_from_xy(xy, config.pattern_plane)
    noisy = directions_from_xy(xy + rng.normal(0.0, noise_deg, xy.shape), config.pattern_plane)
    points = noisy * rng.uniform(5.0, 80.0, (count, 1)) * np.array([1.0, -1.0, -1.0])
    points[rng.random(count) < no_returns] = 0.0
    return points, rays


def as_frame(points: np.ndarray, name: str = "made") -> RecordedFrame:
    return RecordedFrame(name, points * np.array([1.0, -1.0, -1.0]))


@pytest.mark.parametrize(("image", "reverse"), [("mirrored left-right", False), ("turned 180 degrees", True)])
def test_a_made_tele15_frame_gives_back_its_image_laser_order_phases_and_motors(image: str, reverse: bool) -> None:
    sensor = truth("livox_tele15", image, reverse, (800.0, -1200.0), (0.7, -2.1))
    points, rays = made_frame(sensor, first_sample=3)
    started = time.perf_counter()
    fit = fit_recording(load_preset("livox_tele15"), as_frame(points))
    assert 0.0 < fit.seconds <= time.perf_counter() - started  # the time fit's report gives, the fit's own
    # A turned image with the lasers reversed is the same pattern as the other way round to within the laser
    # spacing, so the image and the order are judged together, by what the fitted track does.
    assert (fit.image, fit.laser_order == "reversed") in {(image, reverse), ("as printed", not reverse),
                                                            ("mirrored top-bottom", not reverse)}
    assert fit.ppm == pytest.approx((800.0, -1200.0), abs=150.0)
    assert fit.median_deg < 0.02 and fit.window_median_deg.max() < 0.03
    assert fit.random_median_deg > 1.0 and 0.2 < fit.no_return_share < 0.3
    # The fitted preset replays the frame's rays (the noise-free ones) from its first row.
    replay = make_pattern(fit.config).take(points.shape[0]).xy_deg
    error = angle_deg(directions_from_xy(replay, fit.config.pattern_plane), rays)
    assert np.median(error) < 0.01


def test_the_image_transforms_are_exact_and_a_spin_turns_the_other_way() -> None:
    for name in ("livox_tele15", "livox_horizon"):
        config = load_preset(name)
        ours = make_pattern(config).take(20_000).xy_deg
        for image, signs in IMAGES.items():
            theirs = make_pattern(imaged_config(config, image)).take(20_000).xy_deg
            np.testing.assert_allclose(theirs, ours * signs, atol=1e-9)
    mid360 = load_preset("livox_mid360")
    ours = make_pattern(mid360).take(20_000).xy_deg
    theirs = make_pattern(imaged_config(mid360, "mirrored left-right")).take(20_000).xy_deg
    azimuth = (theirs[:, 0] + ours[:, 0] + 180.0) % 360.0 - 180.0
    np.testing.assert_allclose(azimuth, 0.0, atol=1e-9)
    np.testing.assert_allclose(theirs[:, 1], ours[:, 1], atol=1e-9)
    # Seen from above, the shipped Mid-360 turns counter-clockwise (the azimuth, positive to the right, falls).
    steps = np.diff(np.unwrap(np.radians(ours[::4, 0])))
    assert np.mean(steps < 0) > 0.9


def test_a_frame_whose_rows_were_sorted_or_that_is_another_heads_is_refused() -> None:
    sensor = truth("livox_tele15", "as printed", False, (0.0, 0.0), (0.0, 0.0))
    points, _ = made_frame(sensor, first_sample=0, seconds=0.01)
    order = np.lexsort((points[:, 1], points[:, 2]))
    with pytest.raises(LivoxVizError, match="not this head's scan in firing order"):
        fit_recording(load_preset("livox_tele15"), as_frame(points[order]))
    other, _ = made_frame(load_preset("livox_mid40_risley"), first_sample=0, seconds=0.024)
    with pytest.raises(LivoxVizError, match="random phases"):
        fit_recording(load_preset("livox_tele15"), as_frame(other))
    few = points.copy()
    few[400:] = 0.0
    returns = int(few.any(axis=1).sum())
    with pytest.raises(LivoxVizError, match=rf"{returns} of its 2,400 rows have a return; allowed: at least 1,000"):
        fit_recording(load_preset("livox_tele15"), as_frame(few))
    with pytest.raises(LivoxVizError, match="no fixed track"):
        fit_recording(load_preset("livox_mid70"), as_frame(points))


def write_pcd(path: Path, points: np.ndarray, intensity: np.ndarray) -> None:
    header = (f"# .PCD v0.7\nVERSION 0.7\nFIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\n"
              f"WIDTH {len(points)}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {len(points)}\nDATA ascii\n")
    rows = np.column_stack([points, intensity])
    path.write_text(header + "\n".join(" ".join(f"{v:.6f}" for v in row) for row in rows) + "\n")


def test_fit_recording_reads_a_pcd_guesses_its_head_and_writes_its_twin(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    sensor = truth("livox_tele15", "mirrored left-right", False, (-1500.0, -1560.0), (1.0, 2.0))
    points, rays = made_frame(sensor, first_sample=2, seconds=0.04)
    frame = tmp_path / "frame.pcd"
    write_pcd(frame, points, np.where(points.any(axis=1), 40.0, 0.0))
    out = tmp_path / "twin.json"
    assert main(["fit", str(frame), "--out", str(out), "--frame-seconds", "0.04"]) == 0
    text = capsys.readouterr().out
    assert "livox_tele15 (guessed" in text and "mirrored left-right" in text and "per 2 ms window" in text
    assert "32-63: 100%" in text  # the reflectivity histogram of the returns
    twin = load_preset(out)
    replay = make_pattern(twin).take(points.shape[0]).xy_deg
    assert np.median(angle_deg(directions_from_xy(replay, twin.pattern_plane), rays)) < 0.01


def test_the_frame_readers_read_the_same_rows_from_pcd_ply_and_csv(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    points = rng.normal(0.0, 10.0, (500, 3))
    points[::7] = 0.0
    write_pcd(tmp_path / "a.pcd", points, np.full(500, 9.0))
    binary = np.zeros(500, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "u1")])
    for i, axis in enumerate("xyz"):
        binary[axis] = points[:, i]
    binary["intensity"] = 9
    (tmp_path / "a.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 500\nproperty float x\n"
                                     b"property float y\nproperty float z\nproperty uchar intensity\nend_header\n"
                                     + binary.tobytes())
    times_ns = np.arange(500) * 4_167
    (tmp_path / "a.csv").write_text("x,y,z,reflectivity,offset_time,line\n" + "\n".join(
        f"{x:.6f},{y:.6f},{z:.6f},9,{t},{i % 6}" for i, ((x, y, z), t) in enumerate(zip(points, times_ns,
                                                                                       strict=True))))
    for name in ("a.pcd", "a.ply", "a.csv"):
        rows = read_frame_rows(tmp_path / name)
        np.testing.assert_allclose(rows.points_m, points, atol=1e-5)
        assert np.array_equal(rows.returned, points.any(axis=1)) and np.all(rows.reflectivity == 9)
    rows = read_frame_rows(tmp_path / "a.csv")
    np.testing.assert_allclose(rows.times_s, times_ns * 1e-9)
    assert np.array_equal(rows.lasers, np.arange(500) % 6)


@pytest.mark.parametrize(("text", "message"), [
    ("VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nPOINTS 2\nDATA binary_compressed\n",
     "DATA binary_compressed; allowed: ascii or binary"),
    ("VERSION 0.7\nFIELDS x y i\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nPOINTS 1\nDATA ascii\n1 2 3\n",
     "allowed: fields x, y and z"),
    ("VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nPOINTS 1\nDATA ascii\n1 nan 3\n",
     "NaN or infinite"),
    ("VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nPOINTS 3\nDATA binary\n" + "\0" * 20,
     "ends after 1 of its 3 points"),
])
def test_a_bad_frame_file_gets_one_line(tmp_path: Path, text: str, message: str,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "bad.pcd"
    path.write_bytes(text.encode("latin-1"))
    with pytest.raises(LivoxVizError, match=message):
        read_frame_rows(path)
    assert main(["fit", str(path), "--preset", "livox_tele15"]) == 2
    error = capsys.readouterr().err.strip()
    assert "\n" not in error and message.split(";")[0] in error


def test_an_lvx_our_scan_wrote_is_fitted_back_to_the_preset_that_scanned_it(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """End to end: scan --out x.lvx (LVX 1.1, per-point times and lines as the drivers rebuild them), then fit
    RECORDING: the file's device type names the head, and the preset comes back as it is (no image, no laser
    moved, motors at nominal, within the file's 1 mm steps)."""
    lvx = tmp_path / "scan.lvx"
    assert main(["scan", "--preset", "livox_tele15", "--seconds", "0.03", "--scene", "urban", "--out",
                 str(lvx)]) == 0
    capsys.readouterr()
    assert main(["fit", str(lvx), "--frame-seconds", "0.03"]) == 0
    text = capsys.readouterr().out
    assert "livox_tele15 (the file's device type 2)" in text
    assert "the preset's track itself (not mirrored)" in text and "its first row is laser 0" in text
    ppm = [float(word) for word in text.split("motor speeds")[1].split("\n")[0].replace("ppm", " ").split()
           if word.lstrip("+-").isdigit()]
    assert len(ppm) == 2 and max(abs(value) for value in ppm) <= 20
    median = float(text.split("residual         median ")[1].split(" deg")[0])
    assert median < 0.01
