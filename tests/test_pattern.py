"""The rosette generator against the maths of scan-model.md sections 2-4."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from livox_viz import ScanPattern, SensorConfig
from livox_viz.config.presets import list_presets
from livox_viz.patterns.rosette import arc_xy, config_arc_xy, figure8_template, petal_xy

from .conftest import small_config


def arc_at(cfg: SensorConfig, big_x: float) -> np.ndarray:
    """The arc point at the document's X (X = -(i/W)^p)."""
    index = cfg.data_width * (-big_x) ** (1.0 / cfg.spacing_exponent)
    return config_arc_xy(cfg, np.array([index]))[0]


def slope_at(cfg: SensorConfig, big_x: float, eps: float = 1e-7) -> float:
    a, b = arc_at(cfg, big_x - eps), arc_at(cfg, big_x + eps)
    return (b[1] - a[1]) / (b[0] - a[0])


def test_arc_ends_and_top(mid70: SensorConfig) -> None:
    c, r, h = mid70.camera_fov / 2, mid70.camera_fov / 4, mid70.petal_height
    np.testing.assert_allclose(arc_at(mid70, 0.0), [0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(arc_at(mid70, -1.0), [-c, 0.0], atol=1e-12)
    np.testing.assert_allclose(arc_at(mid70, -0.5), [-r, h], atol=1e-12)


def test_arc_tangents(mid70: SensorConfig) -> None:
    # Vertical at the tip, horizontal at the top, from both halves.
    assert abs(slope_at(mid70, -1.0 + 1e-6)) > 1e3
    assert abs(slope_at(mid70, -0.5 - 1e-4)) < 1e-2
    assert abs(slope_at(mid70, -0.5 + 1e-4)) < 1e-2


def test_both_halves_meet_continuously(mid70: SensorConfig) -> None:
    left, right = arc_at(mid70, -0.5 - 1e-9), arc_at(mid70, -0.5 + 1e-9)
    np.testing.assert_allclose(left, right, atol=1e-6)


def test_centre_half_is_the_circle_with_sagitta_h(mid70: SensorConfig) -> None:
    c, r, h = mid70.camera_fov / 2, mid70.camera_fov / 4, mid70.petal_height
    radius = ((c / 2) ** 2 + h**2) / (2 * h)
    xs = -np.linspace(0, 0.5, 11)
    points = np.array([arc_at(mid70, x) for x in xs])
    np.testing.assert_allclose(points[:, 0], xs * c, atol=1e-12)
    np.testing.assert_allclose(np.hypot(points[:, 0] + r, points[:, 1] - (h - radius)), radius, atol=1e-9)


def test_tip_half_formula(mid70: SensorConfig) -> None:
    r, h, q = mid70.camera_fov / 4, mid70.petal_height, mid70.tip_exponent
    for big_x in (-0.6, -0.75, -0.9):
        a = big_x * math.pi
        expected = [-r * abs(math.cos(a)) ** q - r, h * abs(math.sin(a)) ** q]
        np.testing.assert_allclose(arc_at(mid70, big_x), expected, atol=1e-12)


def test_petal_closes_and_samples_centre_and_tip_once(mid70: SensorConfig) -> None:
    petal = petal_xy(mid70)
    w = mid70.data_width
    assert petal.shape == (2 * w, 2)
    np.testing.assert_allclose(petal[0], [0, 0], atol=1e-12)
    np.testing.assert_allclose(petal[w], [-mid70.camera_fov / 2, 0], atol=1e-12)
    # The petal's last point is one step from the centre where the next petal starts.
    step = np.hypot(*(petal[-1] - petal[0]))
    assert step == pytest.approx(np.hypot(*(petal[1] - petal[0])), rel=1e-9)
    # Lower half mirrors the upper half.
    np.testing.assert_allclose(petal[w + 1 :][::-1] * [1, -1], petal[1:w], atol=1e-12)


def test_figure8_traversal_order(mid70: SensorConfig) -> None:
    w = mid70.data_width
    path = figure8_template(mid70)
    arcs = [path[k * w : (k + 1) * w] for k in range(4)]
    expect = [  # (sign of x, sign of y, |x| growing?)
        (-1, +1, True),
        (-1, -1, False),
        (+1, +1, True),
        (+1, -1, False),
    ]
    for arc, (sx, sy, outward) in zip(arcs, expect, strict=True):
        assert np.all(sx * arc.real >= -1e-12) and np.all(sy * arc.imag >= -1e-12)
        growth = np.diff(np.abs(arc.real))
        assert np.all(growth > 0) if outward else np.all(growth < 0)
    # One smooth path: no jump larger than the largest step inside an arc.
    steps = np.abs(np.diff(np.concatenate([path, path[:1]])))
    assert steps.max() <= np.abs(np.diff(arcs[0])).max() * 1.0001


def test_all_points_inside_fov(mid70: SensorConfig) -> None:
    chunk = ScanPattern(mid70, seed=3).take(mid70.points_per_figure * 2)
    radius = np.hypot(chunk.xy_deg[:, 0], chunk.xy_deg[:, 1])
    assert radius.max() <= mid70.camera_fov / 2 + 1e-9
    assert radius.max() > mid70.camera_fov / 2 - 1e-9


def flower_angles(pattern: ScanPattern, cfg: SensorConfig, flowers: int) -> np.ndarray:
    """Figure-8 rotations, ``(flowers, N8)`` degrees."""
    chunk = pattern.take(cfg.points_per_flower * flowers)
    return chunk.figure8_angle_deg.reshape(flowers, cfg.figure8_per_flower)


@pytest.mark.parametrize("n8", [1, 3, 10])
def test_flower_orientations_are_a_permutation_of_the_grid(n8: int) -> None:
    cfg = small_config(other_params=(100, 2, 1.4, 1.18, n8, 4, 0.7, 0))
    angles = flower_angles(ScanPattern(cfg, seed=5), cfg, 12)
    spacing = 180.0 / n8
    orders = []
    for flower in angles:
        steps = np.mod(flower - flower[0], 360.0) / spacing
        np.testing.assert_allclose(steps, np.round(steps), atol=1e-9)
        steps = np.round(steps).astype(int)
        steps = np.where(steps >= n8, steps - 2 * n8, steps)
        assert sorted(steps - steps.min()) == list(range(n8))
        orders.append(tuple(steps - steps.min()))
    if n8 >= 3:
        assert len(set(orders)) > 1, "every flower scanned its figure-8s in the same order"


def flower_phase(angles: np.ndarray, spacing: float) -> np.ndarray:
    """phi_flower modulo the petal spacing, ``(flowers,)``."""
    return np.mod(angles[:, 0], spacing)


def test_flower_steps_without_jitter_are_exact() -> None:
    cfg = small_config(other_params=(100, 2, 1.4, 1.18, 3, 4, 0.0, 0))
    angles = flower_angles(ScanPattern(cfg, seed=1), cfg, 9)
    spacing, step = 60.0, 15.0
    expected = np.mod((np.arange(9) % 4) * step, spacing)
    np.testing.assert_allclose(flower_phase(angles, spacing), expected, atol=1e-9)


@pytest.mark.parametrize("scope", ["flower", "figure"])
def test_offset_accumulates_by_scope(scope: str) -> None:
    jitter = 2.0
    cfg = small_config(other_params=(100, 2, 1.4, 1.18, 3, 4, jitter, 0), jitter_scope=scope)
    flowers = 400
    angles = flower_angles(ScanPattern(cfg, seed=2), cfg, flowers)
    spacing, step = 60.0, 15.0
    nominal = (np.arange(flowers) % 4) * step
    offset = np.unwrap(np.mod(flower_phase(angles, spacing) - nominal, spacing), period=spacing)
    increments = np.diff(offset)
    assert offset[0] == pytest.approx(0.0, abs=1e-9)
    assert increments.min() >= -1e-9 and increments.max() <= jitter + 1e-9
    if scope == "flower":
        assert np.all(increments > 0)
        assert increments.mean() == pytest.approx(jitter / 2, rel=0.15)
    else:
        boundary = (np.arange(1, flowers) % 4) == 0
        assert np.all(increments[~boundary] == pytest.approx(0.0, abs=1e-9))
        assert np.all(increments[boundary] > 0)
        assert increments[boundary].mean() == pytest.approx(jitter / 2, rel=0.2)


def test_point_times_and_labels(mid70: SensorConfig) -> None:
    pattern = ScanPattern(mid70, seed=0)
    pattern.take(123_457)
    chunk = pattern.take(60_000)
    k = np.arange(123_457, 183_457)
    assert np.array_equal(chunk.t, k / 100_000.0)
    assert np.array_equal(chunk.arc, k // 250)
    assert np.array_equal(chunk.petal, k // 500)
    assert np.array_equal(chunk.figure8, k // 1000)
    assert np.array_equal(chunk.flower, k // 10_000)
    assert np.array_equal(chunk.figure, k // 50_000)
    assert np.array_equal(chunk.frame, k // 10_000)


def test_frames_are_whole_and_continuous(mid70: SensorConfig) -> None:
    pattern = ScanPattern(mid70, seed=4)
    frames = [pattern.next_frame() for _ in range(3)]
    assert [len(f) for f in frames] == [10_000] * 3
    assert [set(f.frame.tolist()) for f in frames] == [{0}, {1}, {2}]
    whole = ScanPattern(mid70, seed=4).take(30_000)
    assert np.array_equal(np.concatenate([f.xy_deg for f in frames]), whole.xy_deg)


def test_next_frame_mid_frame_returns_the_rest() -> None:
    cfg = small_config()
    pattern = ScanPattern(cfg)
    pattern.take(7)
    rest = pattern.next_frame()
    assert len(rest) == cfg.points_per_frame - 7 and set(rest.frame.tolist()) == {0}


@pytest.mark.parametrize("data_height", [8, 7, 13])
def test_odd_chunks_equal_one_take(data_height: int) -> None:
    # Frame, figure-8, flower and figure boundaries fall inside the chunks.
    cfg = small_config(data_height=data_height)
    sizes = [1, 77, 333, 79, 1001, 5, 2311]
    pattern = ScanPattern(cfg, seed=9)
    parts = [pattern.take(n) for n in sizes]
    whole = ScanPattern(cfg, seed=9).take(sum(sizes))
    assert np.array_equal(np.concatenate([p.xy_deg for p in parts]), whole.xy_deg)
    assert np.array_equal(np.concatenate([p.t for p in parts]), whole.t)
    for name in ("frame", "arc", "petal", "figure8", "flower", "figure"):
        assert np.array_equal(np.concatenate([getattr(p, name) for p in parts]), getattr(whole, name))


def test_chunks_across_many_random_blocks() -> None:
    # Tiny figure-8s: one take spans several blocks of random draws.
    cfg = small_config(data_width=1, other_params=(100, 2, 1.4, 1.18, 1, 1, 1.0, 0))
    pattern = ScanPattern(cfg, seed=1)
    parts = [pattern.take(n) for n in (5000, 17_000, 3)]
    whole = ScanPattern(cfg, seed=1).take(22_003)
    assert np.array_equal(np.concatenate([p.xy_deg for p in parts]), whole.xy_deg)


def test_determinism_and_seed(mid70: SensorConfig) -> None:
    a = ScanPattern(mid70, seed=11).take(60_000).xy_deg
    b = ScanPattern(mid70, seed=11).take(60_000).xy_deg
    c = ScanPattern(mid70, seed=12).take(60_000).xy_deg
    assert a.tobytes() == b.tobytes()
    assert not np.array_equal(a, c)


def test_take_until_and_skip(mid70: SensorConfig) -> None:
    pattern = ScanPattern(mid70)
    assert len(pattern.take_until(0.0123)) == 1230
    pattern.skip(770)
    assert pattern.time == pytest.approx(0.02)
    chunk = pattern.take(10)
    assert np.array_equal(chunk.xy_deg, ScanPattern(mid70).take(2010).xy_deg[2000:])


@pytest.mark.parametrize(
    "changes",
    [
        dict(data_width=1),
        dict(data_height=1),
        dict(other_params=(100, 2, 1.4, 1.18, 1, 1, 0, 0)),
        dict(other_params=(100, 2, 0.2, 1.18, 3, 2, 1, 0)),
        dict(other_params=(100, 2, 5, 1.18, 3, 2, 1, 0)),
        dict(other_params=(100, 2, 1.4, 0.3, 3, 2, 1, 0)),
        dict(other_params=(100, 2, 1.4, 4, 3, 2, 1, 0)),
        dict(camera_fov=1.0),
        dict(camera_fov=179.0),
        dict(camera_fov=1.0, other_params=(100, 45, 1.4, 0.3, 3, 2, 360, 0)),
    ],
)
def test_extreme_values_stay_finite_and_inside(changes: dict) -> None:
    cfg = small_config(**changes)
    chunk = ScanPattern(cfg, seed=0).take(cfg.points_per_figure * 3 + 17)
    assert np.all(np.isfinite(chunk.xy_deg))
    assert np.hypot(chunk.xy_deg[:, 0], chunk.xy_deg[:, 1]).max() <= cfg.camera_fov / 2 + 1e-9


def test_wide_petal_arc_is_continuous() -> None:
    # h > FOV/4: the centre half is sampled along its own circle, still meeting at the top.
    index = np.linspace(0, 100, 20001)
    arc = arc_xy(index, 100, 20.0, 8.0, 1.0, 1.0)
    assert np.abs(np.diff(arc, axis=0)).max() < 0.05
    np.testing.assert_allclose(arc[0], [0, 0], atol=1e-9)


def test_memory_of_the_random_draws_stays_bounded(mid70: SensorConfig) -> None:
    pattern = ScanPattern(mid70)
    for _ in range(2000):
        pattern.next_frame()
    assert len(pattern._blocks) <= 2


def test_jitter_scope_changes_only_later_flowers(mid70: SensorConfig) -> None:
    flower = ScanPattern(mid70, seed=0).take(mid70.points_per_flower).xy_deg
    figure = ScanPattern(replace(mid70, jitter_scope="figure"), seed=0).take(mid70.points_per_flower).xy_deg
    assert np.array_equal(flower, figure)


@pytest.mark.parametrize("preset", [info.name for info in list_presets() if info.shipped])
def test_every_stream_gives_the_same_points_however_it_is_cut(preset: str) -> None:
    """The scan takes a batch of frames as one run of the stream: its points must be the frames' own, bit for
    bit, wherever the cuts fall (ten minutes into the scan too, where a spin's turn is large)."""
    from livox_viz import load_preset
    from livox_viz.patterns.factory import make_pattern

    config = load_preset(preset)
    start = 600 * int(config.point_rate)
    count = 3 * config.points_per_frame + 777
    whole = make_pattern(config, seed=4)
    whole.skip(start)
    expected = whole.take(count).xy_deg
    cut = make_pattern(config, seed=4)
    cut.skip(start)
    bounds = np.sort(np.random.default_rng(len(preset)).choice(np.arange(1, count), 9, replace=False))
    parts = [cut.take(int(high - low)).xy_deg for low, high in zip([0, *bounds], [*bounds, count], strict=True)]
    np.testing.assert_array_equal(np.concatenate(parts), expected)
