"""Reading measured patterns, fitting the model to them, comparing."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from livox_viz import LivoxVizError, ScanPattern, SensorConfig, load_preset
from livox_viz.cli import main
from livox_viz.fitting.compare import compare
from livox_viz.fitting.reference import ReferencePattern, load_reference
from livox_viz.fitting.rosette_fit import fit_reference
from livox_viz.patterns.metrics import window_coverage


def as_reference(config: SensorConfig, seconds: float, seed: int = 3) -> ReferencePattern:
    xy = ScanPattern(config, seed=seed).take(round(seconds * config.point_rate)).xy_deg
    return ReferencePattern("model", xy, np.arange(len(xy)) / config.point_rate, float(config.point_rate))


@pytest.mark.parametrize(
    "config",
    [
        SensorConfig(),
        SensorConfig(camera_fov=38.4, other_params=(100, 2.0, 1.8, 0.9, 7, 3, 2.0, 0)),
        SensorConfig(data_width=120, data_height=50, camera_fov=60, other_params=(100, 4.0, 1.1, 1.5, 12, 4, 0.5, 0)),
        SensorConfig(camera_fov=50, other_params=(100, 3, 1.4, 1.18, 5, 6, 1.5, 0), jitter_scope="figure"),
        SensorConfig(other_params=(100, 3, 1.4, 1.18, 8, 4, 0, 0)),
    ],
)
def test_known_answer_fit(config: SensorConfig) -> None:
    result = fit_reference(as_reference(config, 2.0))
    fitted = result.config
    assert abs(fitted.camera_fov - config.camera_fov) <= 0.05
    assert abs(fitted.petal_height - config.petal_height) <= 0.05
    assert abs(fitted.spacing_exponent - config.spacing_exponent) <= 0.05
    assert abs(fitted.tip_exponent - config.tip_exponent) <= 0.05
    assert fitted.figure8_per_flower == config.figure8_per_flower
    assert fitted.flowers_per_figure == config.flowers_per_figure
    assert fitted.jitter_scope == config.jitter_scope
    assert fitted.jitter_max_deg == pytest.approx(config.jitter_max_deg, abs=0.25 * config.jitter_max_deg + 1e-9)
    assert fitted.data_width == config.data_width and fitted.point_rate == config.point_rate
    assert result.shape.rms_deg < 1e-3


def write_npy_table(path: Path, xy_deg: np.ndarray, degrees: bool = False) -> None:
    """Our pattern as the reference .npy form: [theta azimuth about +z, phi elevation], x fwd y left z up."""
    alpha = np.radians(np.hypot(xy_deg[:, 0], xy_deg[:, 1]))
    beta = np.arctan2(xy_deg[:, 1], xy_deg[:, 0])
    d = np.column_stack([np.cos(alpha), -np.sin(alpha) * np.cos(beta), np.sin(alpha) * np.sin(beta)])
    table = np.column_stack([np.arctan2(d[:, 1], d[:, 0]), np.arcsin(d[:, 2])])
    np.save(path, np.degrees(table) if degrees else table)


def test_npy_and_csv_readers_round_trip(tmp_path: Path, mid70: SensorConfig) -> None:
    xy = ScanPattern(mid70).take(3000).xy_deg
    write_npy_table(tmp_path / "t.npy", xy)
    back = load_reference(tmp_path / "t.npy", rate=50_000)
    np.testing.assert_allclose(back.xy_deg, xy, atol=1e-9)
    assert back.t[-1] == pytest.approx(2999 / 50_000)
    table = np.load(tmp_path / "t.npy")
    rows = np.column_stack([np.arange(len(table)), np.degrees(table[:, 0]), 90 - np.degrees(table[:, 1])])
    csv = tmp_path / "t.csv"
    np.savetxt(csv, rows, delimiter=",", header="Time/s,Azimuth/deg,Zenith/deg", comments="", fmt="%.12f")
    np.testing.assert_allclose(load_reference(csv, rate=50_000).xy_deg, xy, atol=1e-8)


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda p: np.save(p, np.zeros((10, 3))), r"shape \(10, 3\); allowed: \(n, 2\)"),
        (lambda p: np.save(p, np.full((100, 2), np.nan)), "NaN or infinite"),
        (lambda p: write_npy_table(p, ScanPattern(load_preset("livox_mid70")).take(3000).xy_deg, degrees=True),
         "look like degrees"),
        (lambda p: np.save(p, np.zeros((5, 2))), "at least a petal"),
        (lambda p: p.write_bytes(b"not numpy"), "not a NumPy"),
    ],
)
def test_bad_reference_files(tmp_path: Path, make, message: str) -> None:
    path = tmp_path / "bad.npy"
    make(path)
    with pytest.raises(LivoxVizError, match=message):
        load_reference(path)


def test_too_few_points_for_a_fit() -> None:
    config = SensorConfig()
    with pytest.raises(LivoxVizError, match=r"allowed: at least 0\.1 s"):
        fit_reference(as_reference(config, 0.003))


def test_compare_identical_and_shifted(mid70: SensorConfig) -> None:
    reference = as_reference(mid70, 1.0, seed=0)
    same = compare(mid70, reference, seed=0, seconds=(0.1, 0.5, 1.0))
    np.testing.assert_array_equal(same.coverage_ours, same.coverage_reference)
    np.testing.assert_array_equal(same.density_ours, same.density_reference)
    shifted = ReferencePattern("shifted", reference.xy_deg + np.array([3.0, 0.0]), reference.t, reference.rate)
    moved = compare(mid70, shifted, seed=0, seconds=(0.1, 0.5, 1.0))
    # Each is counted in its own field of view (the shifted one's outline is its disk, moved): the same
    # pattern covers it alike, but its density off the boresight is not ours.
    assert shifted.field_of_view.shape == "outline"
    assert np.abs(moved.coverage_ours - moved.coverage_reference).max() < 0.005
    assert np.abs(moved.density_ours - moved.density_reference).max() > 0.1 * moved.density_ours.max()


def test_window_coverage_of_a_repeating_pattern() -> None:
    config = SensorConfig(other_params=(100, 3, 1.4, 1.18, 1, 1, 0, 0))  # every figure-8 the same
    xy = ScanPattern(config).take(100_000).xy_deg
    flower = window_coverage(xy, config.point_rate, (0.1,), config.half_fov_deg)
    longer = window_coverage(xy, config.point_rate, (0.5,), config.half_fov_deg)
    assert flower[0] == pytest.approx(longer[0], abs=1e-9)


def test_fitted_mid40_preset_against_the_table() -> None:
    reference = load_reference("mid40")
    preset = load_preset("livox_mid40")
    result = compare(preset, reference, seed=0, seconds=(0.1, 0.5, 1.0))
    assert np.abs(result.coverage_ours - result.coverage_reference).max() < 0.03
    assert result.coverage_reference == pytest.approx([0.207, 0.729, 0.943], abs=0.005)
    assert preset.camera_fov == pytest.approx(2 * reference.alpha_deg.max(), abs=0.3)


def test_fit_counts_the_tables_coverage_as_compare_does() -> None:
    """Each pattern's coverage in its own field of view: the table's curve that fit reports is compare's, though
    the fitted cone (Mid-70: 35.06 deg) is narrower than the table's own (35.22)."""
    reference = load_reference("mid70")
    fitted = fit_reference(reference)
    assert fitted.config.half_fov_deg < reference.field_of_view.size_deg[0] / 2 - 0.1
    compared = compare(fitted.config, reference, seed=0, seconds=fitted.seconds)
    np.testing.assert_allclose(fitted.coverage_reference, compared.coverage_reference, rtol=0, atol=1e-12)


def test_fit_cli_on_mid40(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "mid40.json"
    assert main(["fit", "mid40", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    rms = float(text.split("rms ")[1].split()[0])
    assert rms <= 0.25 and "warning" not in text  # a rosette head's own table: no rough-fit warning
    fitted = load_preset(str(out))
    # The shipped preset is the fit with the Mid-40's return model (LivoxVizReturns), which a bare fit of the Mid-40's
    # table takes from the table's own sensor (it took the default's, the Mid-70's, before).
    assert "return model of livox_mid40_risley, the Livox Mid-40's" in text
    assert fitted == load_preset("livox_mid40")
    assert main(["compare", "--config", str(out), "mid40", "--plot", str(tmp_path / "c.png")]) == 0
    assert (tmp_path / "c.png").stat().st_size > 10_000


def test_fit_cli_bad_input(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.npy"
    np.save(bad, np.ones((10, 4)))
    assert main(["fit", str(bad)]) == 2
    assert "allowed: (n, 2)" in capsys.readouterr().err


@pytest.mark.parametrize(("alpha", "petals"), [
    ([0, 5, 10, 5, 0, 10, 5, 0, 3], [(0, 2, 4)]),  # a rise of one sample to the tip is no whole petal
    ([0, 5, 10, 5, 0, 5, 10, 0, 3], [(0, 2, 4)]),  # nor is a fall of one sample from it
    ([0, 5, 10, 5, 0, 5, 10, 5, 0, 3], [(0, 2, 4), (4, 6, 8)]),  # two samples each way are
    ([0, 5, 10, 5, 0, 5, 7, 5, 0, 3], [(0, 2, 4)]),  # a tip under three quarters of the top is no petal
])
def test_petals_need_two_samples_each_side_of_a_tip_near_the_top(alpha: list[float],
                                                                 petals: list[tuple[int, int, int]]) -> None:
    from livox_viz.fitting.rosette_fit import find_petals

    found = find_petals(np.column_stack([np.asarray(alpha, dtype=float), np.zeros(len(alpha))]))
    assert list(zip(found.start.tolist(), found.tip.tolist(), found.end.tolist(), strict=True)) == petals


@pytest.mark.parametrize(("rms_deg", "half_fov_deg", "rough"), [
    (0.219, 19.1, False),  # the Mid-40's table (1.1 % of its half-angle)
    (0.129, 35.1, False),  # the Mid-70's
    (0.5, 20.0, False),    # 2.5 % exactly: still a fit
    (0.501, 20.0, True),
    (1.724, 34.4, True),   # the Avia's table (5.0 %)
    (3.054, 53.8, True),   # the HAP's (5.7 %), fitted without a word before
])
def test_a_rosette_fit_far_off_its_petals_says_so(rms_deg: float, half_fov_deg: float, rough: bool) -> None:
    from livox_viz.fitting.rosette_fit import ShapeFit

    shape = ShapeFit(camera_fov=2 * half_fov_deg, petal_height=5.0, spacing_exponent=1.3, tip_exponent=1.1,
                     rms_deg=rms_deg, p95_deg=2 * rms_deg, points_per_arc=10.0, petals=40)
    warning = shape.rough_warning()
    assert (warning is not None) == rough
    if rough:
        share = f"{100 * rms_deg / half_fov_deg:.1f} % of the {half_fov_deg:.3g} deg half-angle"
        assert f"{rms_deg:.3g} deg rms off its petals, {share}" in warning
        assert "a rosette cannot draw this scan" in warning


@pytest.mark.parametrize(("rate", "lasers", "layout"), [
    (100_000.0, 4, (250, 40, 10)),   # the base makes the table's rate in whole groups: its own layout kept
    (200_000.0, 4, None),            # another rate: laid out anew at the table's
    (100_000.0, 32, None),           # the base's rate, but its 10,000-point frames hold no whole groups of 32
])
def test_a_fitted_track_plays_at_its_table_s_rate_in_whole_firing_groups(rate: float, lasers: int,
                                                                        layout: tuple[int, int, int] | None) -> None:
    from livox_viz.cli.fit_commands import _at_table_rate

    base = load_preset("livox_mid70")
    xy = np.zeros((int(rate), 2))
    table = ReferencePattern("table", xy, np.arange(xy.shape[0]) / rate, rate)
    config = _at_table_rate(base, table, lasers, lasers)
    assert config.point_rate == rate and config.points_per_frame % lasers == 0
    if layout is not None:
        assert (config.data_width, config.data_height, config.data_check_freq) == layout
    else:
        assert config != base


def test_compare_replays_a_preset_reference_for_4_s_unless_told(capsys: pytest.CaptureFixture[str]) -> None:
    """The documented default of ``compare --seconds`` (how much of a preset reference is replayed)."""
    assert main(["compare", "livox_mid70_risley"]) == 0
    first = capsys.readouterr().out.splitlines()[0]
    assert first == "livox_mid70 against livox_mid70_risley (4 s)"
    assert main(["compare", "livox_mid70_risley", "--seconds", "1.5"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "livox_mid70 against livox_mid70_risley (1.5 s)"
    assert out[1].split() == ["integration", "s", "reference", "%", "ours", "%", "difference", "pp"]
    assert max(float(line.split()[0]) for line in out[2:] if line.split()[0].replace(".", "").isdigit()) == 1.5


@pytest.mark.parametrize(("figure8s", "flowers", "jitter_deg", "scope"), [
    (10, 5, 1.0, "flower"), (7, 3, 0.0, "flower"), (4, 9, 2.0, "figure")])
def test_the_structure_is_read_off_the_figure_8_pairs_tips(figure8s: int, flowers: int, jitter_deg: float,
                                                          scope: str) -> None:
    """N8, Nf, the jitter's scope and (within its draws) its size, from our own rosette's tip angles: the fit's
    first way, before the coverage search it falls back on."""
    from dataclasses import replace

    from livox_viz.fitting.rosette_fit import find_petals, fit_structure_from_pairs

    config = replace(load_preset("livox_mid70").with_param("figure8_per_flower", figure8s)
                     .with_param("flowers_per_figure", flowers).with_param("jitter_max_deg", jitter_deg),
                     jitter_scope=scope)
    xy = ScanPattern(config, seed=0).take(400_000).xy_deg
    found = fit_structure_from_pairs(xy, find_petals(xy))
    assert found is not None and found.method == "figure-8 pairs"
    assert (found.figure8_per_flower, found.flowers_per_figure, found.jitter_scope) == (figure8s, flowers, scope)
    assert (found.jitter_max_deg == 0.0) if jitter_deg == 0.0 else (0.5 * jitter_deg < found.jitter_max_deg
                                                                     <= jitter_deg)


@pytest.mark.parametrize(("slots", "consecutive"), [
    ([], True), ([0], True), ([0, 1, 2, 3], True),
    ([0, 1, 3, 4], False),   # a firing missing (a no-return dropped)
    ([1, 2, 3], False),      # not from the first firing
    ([0, 1, 1, 2], False),   # two rows in one firing (a group printed with one time)
])
def test_a_table_is_consecutive_only_with_every_firing_from_the_first(slots: list[int], consecutive: bool) -> None:
    rate = 1000.0
    table = ReferencePattern("t", np.zeros((len(slots), 2)), np.array(slots, dtype=np.float64) / rate, rate)
    assert table.consecutive is consecutive
