"""The broad phase on rough ground (issue 34, item 4): a tile of an object that is not convex is named by its
sub-boxes, not by its whole box (a terrain tile's box holds the air above its ground)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from livox_viz import load_preset
from livox_viz.casting import returns as returns_module
from livox_viz.casting.beam import TileProxy
from livox_viz.casting.scan import MountedCaster
from livox_viz.patterns.factory import make_pattern
from livox_viz.scene.raycast import EmbreeCaster, casting_in_this_thread
from livox_viz.scene.scenes import open_scene

FRAMES = 3


@pytest.fixture(scope="module")
def terrain() -> tuple:
    scene = open_scene("dense_terrain")
    return scene, EmbreeCaster(scene.mesh)


def _runs(monkeypatch: pytest.MonkeyPatch, scene, caster, tight: bool, frames: int = FRAMES) -> tuple[list, list]:
    """``frames`` datasheet frames of the Mid-70 on the scene, one run each (cast in this thread), with what each
    run's step 2 saw and answered: (covered, near, triangle, leaves, directions, origins, basis, distance)."""
    seen = []
    covered = returns_module.ReturnModel._covered

    def kept(self, leaves, directions, origins, basis, reach, triangle, distance, *rest):
        answer = covered(self, leaves, directions, origins, basis, reach, triangle, distance, *rest)
        seen.append((answer[0].copy(), answer[1].copy(), triangle.copy(), leaves.copy(), directions.copy(),
                     origins.copy(), basis, distance.copy(), reach.copy(), self))
        return answer

    monkeypatch.setattr(returns_module.ReturnModel, "_covered", kept)
    monkeypatch.setattr(TileProxy, "tight", tight)
    config = load_preset("livox_mid70_risley").with_returns_model("datasheet")
    mounted = MountedCaster(config, caster, scene.vehicle_pose, seed=1)
    pattern = make_pattern(config, seed=1)
    per = config.points_per_frame
    with casting_in_this_thread():
        clouds = [mounted.cast(pattern.points(k * per, per)) for k in range(frames)]
    monkeypatch.undo()
    return clouds, seen


def _by_pulse(frame) -> dict[int, tuple]:
    points: dict[int, list] = {}
    for index, xyz, byte in zip(frame.stream_index.tolist(), frame.xyz_sensor.tolist(), frame.reflectivity.tolist(),
                                strict=True):
        points.setdefault(index, []).append((*xyz, byte))
    return {k: tuple(v) for k, v in points.items()}


def test_the_terrain_broad_phase_names_far_fewer_pulses_and_never_one_the_boxes_did_not(
        monkeypatch: pytest.MonkeyPatch, terrain: tuple) -> None:
    """On the dense terrain the boxes alone name over a fifth of the pulses (28 %: measured); the sub-boxes name
    less than half as many, and only pulses the boxes named."""
    scene, caster = terrain
    _, box = _runs(monkeypatch, scene, caster, tight=False)
    _, tight = _runs(monkeypatch, scene, caster, tight=True)
    named_box = sum(int(run[1].sum()) for run in box)
    named_tight = sum(int(run[1].sum()) for run in tight)
    pulses = sum(run[1].size for run in box)
    assert named_box > 0.2 * pulses
    assert named_tight < 0.5 * named_box, (named_tight, named_box)
    for (_, near_box, *_), (_, near_tight, *_) in zip(box, tight, strict=True):
        assert not np.any(near_tight & ~near_box)


def test_every_tile_a_footprint_ray_meets_is_named(monkeypatch: pytest.MonkeyPatch, terrain: tuple) -> None:
    """The broad phase's guarantee, by Embree: rays all over each pulse's footprint cone (the largest half-angle's
    circle, and circles at a third and two thirds of it: every ray of any footprint lies inside) are cast to the
    pulse's reach; a pulse one of whose rays first meets a triangle of a tile other than its hit's own is named by
    the tight broad phase. Thousands of pulses of the dense terrain, many of them grazing (the ground seen at
    under 10 degrees), and hundreds that meet another tile: a test that drops a tile too eagerly (the sub-boxes
    not grown, say) fails here."""
    scene, caster = terrain
    _, tight = _runs(monkeypatch, scene, caster, tight=True, frames=2)
    model = tight[0][-1]
    proxy = model.proxy
    tan_half = model.footprint.tan_half_max
    angles = np.linspace(0.0, 2.0 * math.pi, 24, endpoint=False)
    checked = grazing = meeting = 0
    for _, near, triangle, _, directions, origins, _, _, reach, _ in tight:
        rows = np.flatnonzero(triangle >= 0)
        own = proxy.triangle_tile[triangle[rows]]
        rows = rows[own >= 0]  # hits on the terrain and the other objects of tiles
        u = directions[rows]
        # Two unit vectors across each beam.
        helper = np.where(np.abs(u[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
        a = np.cross(u, helper)
        a /= np.linalg.norm(a, axis=1, keepdims=True)
        b = np.cross(u, a)
        rays, pulse = [], []
        for share in (1.0 / 3.0, 2.0 / 3.0, 1.0):
            for angle in angles:
                spread = share * tan_half * (math.cos(angle) * a + math.sin(angle) * b)
                ray = u + spread
                rays.append(ray / np.linalg.norm(ray, axis=1, keepdims=True))
                pulse.append(rows)
        rays_all = np.concatenate(rays).astype(np.float32)
        pulse_all = np.concatenate(pulse)
        with casting_in_this_thread():
            met = caster.triangle_ids(origins[0], rays_all, float(reach.max())).astype(np.int64)
            far = caster.distances(origins[0], rays_all, float(reach.max()))
        hit = triangle[pulse_all]
        met_tile = np.where(met >= 0, proxy.triangle_tile[np.maximum(met, 0)], -1)
        own_tile = proxy.triangle_tile[hit]
        other = (met >= 0) & (met != hit) & (met_tile >= 0) & (met_tile != own_tile) & (far <= reach[pulse_all])
        # A tile of the hit's convex object is the hit's own (it cannot lie in front of the hit).
        other &= ~(proxy.tile_convex[np.maximum(met_tile, 0)] & (proxy.triangle_part[np.maximum(met, 0)]
                                                                 == proxy.triangle_part[hit]))
        must = np.unique(pulse_all[other])
        assert np.all(near[must]), must[~near[must]][:10]
        checked += rows.size
        meeting += must.size
        planes = caster.face_planes[triangle[rows], :3]
        grazing += int(np.count_nonzero(np.abs(np.sum(planes * u, axis=1)) < math.sin(math.radians(10.0))))
    assert checked > 10000 and grazing > 1000 and meeting > 200, (checked, grazing, meeting)


def test_the_cloud_changes_only_where_a_pulse_is_covered_by_its_own_tile(
        monkeypatch: pytest.MonkeyPatch, terrain: tuple) -> None:
    """Tight against boxes only, same frames, bit for bit: every pulse's points are the same but those of pulses
    the boxes named and the sub-boxes do not, whose footprint is covered only by the hit's own terrain tile (the
    self-cover of a crease, which the broad phase does not name by design: the boxes named it when a neighbouring
    tile's box happened to pass the beam). Those are a small share, and every probe of theirs that Embree finds
    blocked is blocked by the hit's own tile."""
    scene, caster = terrain
    clouds_box, box = _runs(monkeypatch, scene, caster, tight=False)
    clouds_tight, tight = _runs(monkeypatch, scene, caster, tight=True)
    per = box[0][1].size
    differ = set()
    for frame_box, frame_tight in zip(clouds_box, clouds_tight, strict=True):
        a, b = _by_pulse(frame_box), _by_pulse(frame_tight)
        differ |= {k for k in set(a) | set(b) if a.get(k) != b.get(k)}
    explained = set()
    for k, (run_box, run_tight) in enumerate(zip(box, tight, strict=True)):
        covered_box, near_box, triangle, leaves, directions, origins, basis, _, _, model = run_box
        covered_tight, near_tight = run_tight[0], run_tight[1]
        assert set(covered_tight.tolist()) <= set(covered_box.tolist())
        lost = np.setdiff1d(covered_box, covered_tight)
        # Pulses whose sub-rays were cast for the boxes (not clear) and planed for the sub-boxes.
        unnamed = np.flatnonzero(leaves & near_box & ~near_tight)
        explained |= {k * per + int(i) for i in np.concatenate([lost, unnamed])}
        if lost.size:
            probes = basis.rays(lost, directions, model.footprint.probe_offsets).reshape(-1, 3).astype(np.float32)
            with casting_in_this_thread():
                first = caster.triangle_ids(origins[0], probes, model.range_max).astype(np.int64)
            own = model.proxy.triangle_tile[triangle[np.repeat(lost, 4)]]
            assert np.all((first < 0) | (model.proxy.triangle_tile[np.maximum(first, 0)] == own))
    assert differ <= explained, sorted(differ - explained)[:10]
    assert len(differ) < 0.02 * per * FRAMES, len(differ)


def test_a_scene_of_buildings_is_the_same_bit_for_bit(monkeypatch: pytest.MonkeyPatch) -> None:
    """On the urban scene (no terrain) the tight broad phase changes no point."""
    scene = open_scene("urban")
    caster = EmbreeCaster(scene.mesh)
    clouds_box, _ = _runs(monkeypatch, scene, caster, tight=False)
    clouds_tight, _ = _runs(monkeypatch, scene, caster, tight=True)
    for a, b in zip(clouds_box, clouds_tight, strict=True):
        for name in ("stream_index", "xyz_sensor", "xyz_int16", "reflectivity", "range_m"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
