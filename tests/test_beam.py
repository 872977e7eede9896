"""The beam's footprint sampling and its broad phase, against closed forms (issue 17)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh
from scipy import integrate

from livox_viz.casting.beam import SUBRAY_UNIT, SUBRAY_WEIGHTS, TILE_SIZE, WHOLE_CONVEX, TileProxy
from livox_viz.scene.materials import set_face_materials


def test_sub_rays_carry_the_gaussian_energy_of_their_rings() -> None:
    """19 sub-rays: the centre, a ring of 6 and a ring of 12 on the 1/e^2 contour; each carries the energy of
    its Voronoi annulus (bounded half-way between the ring radii) of a Gaussian beam I ~ exp(-2 r^2),
    integrated here numerically."""
    radius = np.hypot(SUBRAY_UNIT[:, 0], SUBRAY_UNIT[:, 1])
    rings = np.unique(np.round(radius, 12))
    assert rings.tolist() == [0.0, 0.5, 1.0]
    assert [int(np.sum(np.isclose(radius, r))) for r in rings] == [1, 6, 12]
    assert radius[0] == 0.0  # the central ray first
    bounds = [0.0, *((rings[:-1] + rings[1:]) / 2), math.inf]
    density = 2.0 / math.pi  # exp(-2 r^2) normalised: its integral over the plane is pi / 2

    def energy(low: float, high: float) -> float:
        return integrate.quad(lambda r: density * math.exp(-2 * r * r) * 2 * math.pi * r, low, high)[0]

    for k, ring in enumerate(rings):
        members = np.isclose(radius, ring)
        np.testing.assert_allclose(SUBRAY_WEIGHTS[members], energy(bounds[k], bounds[k + 1]) / members.sum(),
                                   rtol=1e-9)
    assert SUBRAY_WEIGHTS.sum() == pytest.approx(1.0, abs=1e-12)
    # Each ring's angles are evenly spread and include both axes (an edge along an axis is met exactly).
    for ring, count in ((0.5, 6), (1.0, 12)):
        angles = np.sort(np.degrees(np.arctan2(*SUBRAY_UNIT[np.isclose(radius, ring)][:, ::-1].T)) % 360)
        np.testing.assert_allclose(np.diff(angles), 360 / count, atol=1e-9)
    ring = SUBRAY_UNIT[np.isclose(radius, 1.0)]
    for axis_point in ([1, 0], [0, 1], [-1, 0], [0, -1]):
        assert np.any(np.all(np.isclose(ring, axis_point, atol=1e-12), axis=1))


def box_object(length: float) -> trimesh.Trimesh:
    mesh = trimesh.creation.box((length, 2.0, 2.0))
    faces = len(mesh.faces)
    return set_face_materials(mesh, np.full(faces, 0.5), np.ones(faces), np.zeros(faces))


@pytest.mark.parametrize("length", [20.0, 45.0, 60.0, 120.0])
def test_a_convex_object_is_one_box_up_to_its_size_limit_and_tiles_beyond(length: float) -> None:
    proxy = TileProxy(box_object(length), math.tan(math.radians(0.14)))
    extent = (proxy.high - proxy.low).max(axis=1)
    if length <= WHOLE_CONVEX:
        assert proxy.tiles == 1
        assert extent[0] == pytest.approx(length)
    else:
        assert proxy.tiles >= math.ceil(length / TILE_SIZE)
        assert extent.max() <= TILE_SIZE + 1e-9
        # The tiles cover the object: together they reach from one end to the other.
        assert proxy.low[:, 0].min() == pytest.approx(-length / 2) and proxy.high[:, 0].max() == pytest.approx(
            length / 2)


@pytest.mark.parametrize("plane", ["boresight", "panorama"])
@pytest.mark.parametrize("xy_deg", [(0.0, 0.0), (0.02, -0.03), (12.0, 5.0), (-30.0, 20.0), (3.0, -35.0)])
def test_a_rays_derivatives_by_pattern_angle_are_its_finite_differences(xy_deg: tuple[float, float],
                                                                       plane: str) -> None:
    """The footprint spreads along d(direction)/dx and d/dy per radian (boresight), or along their unit vectors
    (a panoramic head: the azimuth and elevation tangents): the compiled closed forms (both the per-pulse loop's
    and the one-ray helper's) against central differences of the directions themselves."""
    from livox_viz.casting import return_kernels
    from livox_viz.casting.returns import sensor_basis
    from livox_viz.patterns.planes import directions_from_xy

    step_deg = 1e-4
    point = np.array([xy_deg])
    numeric = []
    for axis in (0, 1):
        shift = np.zeros((1, 2))
        shift[0, axis] = step_deg
        delta = directions_from_xy(point + shift, plane) - directions_from_xy(point - shift, plane)
        along = delta[0] / (2 * math.radians(step_deg))
        numeric.append(along / np.linalg.norm(along) if plane == "panorama" else along)
    basis_x, basis_y = sensor_basis(point, plane)
    np.testing.assert_allclose(basis_x[0], numeric[0], atol=1e-7)
    np.testing.assert_allclose(basis_y[0], numeric[1], atol=1e-7)
    return_kernels.kernel("offset_rays")  # the helpers compiled, as the model runs them
    one = np.array(return_kernels._basis_at(*xy_deg, plane == "panorama"))
    np.testing.assert_allclose(one, np.concatenate(numeric), atol=1e-7)


def test_the_broad_phases_ray_box_test_against_points_along_the_ray() -> None:
    """The compiled slab test (does the ray from o meet the box before ``limit``?) against a brute-force
    answer: 4000 points along each segment, any inside the box (rays and boxes random, origins far from 0;
    the rare ray that only grazes within a step of the box is left out)."""
    from livox_viz.casting import return_kernels

    return_kernels.kernel("near")  # the helpers compiled, as the model runs them
    slab = return_kernels._slab
    rng = np.random.default_rng(7)
    agree = hits = 0
    for _ in range(3000):
        origin = rng.uniform(-60, 60, 3)
        low = rng.uniform(-60, 60, 3)
        high = low + rng.uniform(0.5, 30, 3)
        # Half the rays aim near the box, the others anywhere.
        aim = rng.uniform(low - 5, high + 5) - origin if rng.random() < 0.5 else rng.normal(size=3)
        direction = aim / np.linalg.norm(aim)
        if rng.random() < 0.15:  # rays along the axes: an inverse component is infinite
            direction[rng.integers(3)] = 0.0
            direction /= np.linalg.norm(direction)
        limit = rng.uniform(1, 150)
        t = np.linspace(0.0, limit, 4000)
        points = origin + t[:, None] * direction
        inside = np.all((points >= low) & (points <= high), axis=1)
        # Within a sampling step of the box's surface the brute force cannot tell: leave those rays out.
        step = limit / 4000
        margin = np.all((points >= low - step) & (points <= high + step), axis=1)
        if inside.any() != margin.any():
            continue
        inverse = [1.0 / d if d != 0.0 else np.inf for d in direction]
        got = slab(*origin, *inverse, limit, *low, *high)
        assert got == inside.any(), (origin, direction, low, high, limit)
        agree += 1
        hits += bool(got)
    assert agree > 2800 and 200 < hits < agree - 200


@pytest.mark.parametrize("grid", [True, False])
def test_rays_said_to_meet_nothing_meet_nothing_in_embree(grid: bool) -> None:
    """A footprint's ray that :meth:`TileProxy.rays_may_meet` says meets nothing (outside every tile the broad
    phase listed, a convex object's sphere, cylinder and planes, a flat object's box) is one Embree finds
    unblocked: random rays and rays aimed at every vertex and edge of a small box, a wedge, a ball and a pole
    (grazing, where rounding decides; the ball and the pole also by their bounding sphere and cylinder), listed
    from the fixed sensor's direction grid and from the moving one's tree; and most rays through the boxes' air
    are let go."""
    from livox_viz.scene.raycast import EmbreeCaster, casting_in_this_thread

    wedge = trimesh.Trimesh([[6.0, 1.0, 1.0], [6.0, 2.5, 1.0], [6.0, 1.0, -1.0], [7.5, 1.0, 1.0]],
                            [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    wedge.fix_normals()
    pole = trimesh.creation.cylinder(0.08, 3.0, sections=40).apply_translation((3.5, 0.8, 0.0))
    objects = [trimesh.creation.icosphere(2, 0.6).apply_translation((5.0, -1.0, -0.5)), wedge,
               trimesh.creation.box((0.15, 0.15, 0.15)).apply_translation((0.8, -0.4, 0.1)), pole,
               trimesh.Trimesh([[-5.0, -30.0, 1.2], [9.0, -30.0, 1.2], [9.0, 30.0, 1.2], [-5.0, 30.0, 1.2]],
                               [[0, 1, 2], [0, 2, 3]])]
    mesh = trimesh.util.concatenate(objects)
    set_face_materials(mesh, np.full(len(mesh.faces), 0.5), np.ones(len(mesh.faces)),
                       np.repeat(np.arange(len(objects)), [len(o.faces) for o in objects]))
    proxy = TileProxy(mesh, math.tan(math.radians(0.14)))
    assert np.count_nonzero(np.isfinite(proxy.part_sphere[:, 10])) >= 1  # the pole's cylinder
    origin = np.zeros((1, 3))
    boxes = proxy.place(origin, 600.0, np.eye(3) if grid else None)
    rng = np.random.default_rng(3)
    targets = [rng.uniform((0.5, -3.0, -2.0), (9.0, 3.0, 2.0), (20000, 3))]
    for solid in objects[:4]:
        edges = solid.vertices[solid.edges_unique]
        for share in np.linspace(0.0, 1.0, 9):
            targets.append(edges[:, 0] + share * (edges[:, 1] - edges[:, 0]))
    aim = np.concatenate(targets)
    aim = aim + rng.normal(scale=1e-7, size=aim.shape) * rng.integers(0, 2, (len(aim), 1))
    rays = aim / np.linalg.norm(aim, axis=1, keepdims=True)
    rays32 = rays.astype(np.float32)
    limit = np.full(len(rays), 12.0)
    # Each ray is its own pulse's central ray: the broad phase lists what it crosses, the narrow phase answers.
    crossed = np.empty((len(rays), 8), np.int64)
    no_hit = np.full(len(rays), -1)
    proxy.near(np.ones(len(rays), dtype=bool), origin, rays, limit, no_hit, rays if grid else None, boxes, crossed)
    meet = proxy.rays_may_meet(np.arange(len(rays)), rays32, limit, no_hit, origin, crossed)
    with casting_in_this_thread():
        blocked = EmbreeCaster(mesh).occluded(origin[0], rays32, limit)
    assert not np.any(blocked & ~meet), np.flatnonzero(blocked & ~meet)[:10]
    assert blocked.sum() > 5000
    # Rays through a box but not the object in it: most are let go.
    in_a_box = np.zeros(len(rays), dtype=bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        for solid in objects[:4]:
            low, high = solid.bounds
            near, far = low / rays, high / rays
            enter = np.nanmax(np.minimum(near, far), axis=1)
            leave = np.nanmin(np.maximum(near, far), axis=1)
            in_a_box |= (enter < leave) & (leave > 0) & (enter < 12.0)
    air = in_a_box & ~blocked
    assert air.sum() > 300 and np.count_nonzero(~meet[air]) > 0.5 * air.sum()
    # Rays that end at a surface (their limit a hair before, at or beyond Embree's own distance) and rays in the
    # plane of the small box's bottom face from a point of that plane, aimed along it: grazing at its most.
    with casting_in_this_thread():
        distance = EmbreeCaster(mesh).distances(origin[0], rays32, 12.0)
    ends = np.flatnonzero(np.isfinite(distance))
    short = np.concatenate([distance[ends] + step for step in (-1e-4, -1e-6, 0.0, 1e-6, 1e-4)])
    ends = np.tile(ends, 5)
    on_face = np.array([[0.0, -0.4, 0.025]])
    face = np.column_stack([rng.uniform(0.725, 0.875, 4000), rng.uniform(-0.475, -0.325, 4000), np.full(4000, 0.025)])
    along = (face - on_face) / np.linalg.norm(face - on_face, axis=1, keepdims=True)
    for start, directions, reach in ((origin, rays[ends], short), (on_face, along, np.full(len(along), 12.0))):
        crossed = np.empty((len(directions), 8), np.int64)
        no_hit = np.full(len(directions), -1)
        proxy.near(np.ones(len(directions), dtype=bool), start, directions, reach, no_hit, None, proxy.place(
            start, 600.0, None), crossed)
        meet = proxy.rays_may_meet(np.arange(len(directions)), directions.astype(np.float32), reach, no_hit, start,
                                   crossed)
        with casting_in_this_thread():
            blocked = EmbreeCaster(mesh).occluded(start[0], directions.astype(np.float32), reach)
        assert not np.any(blocked & ~meet), np.flatnonzero(blocked & ~meet)[:10]
        assert blocked.sum() > 100


@pytest.mark.parametrize("sensor_in_a_box", [False, True])
def test_the_direction_grid_names_what_the_box_tree_names(sensor_in_a_box: bool) -> None:
    """A fixed sensor's broad phase (boxes filed by direction, :class:`DirectionGrid`) against the moving one's
    (every box, down a tree): the same beams named and the same tiles listed, on a terrain under and behind a
    turned sensor with boxes beside and behind it (cut where they reach behind the sensor, or filed nowhere),
    and a box holding the sensor; beams anywhere around it (those outside the grid test every box) and
    crowded at the grid's edge, 2 off the boresight."""
    from livox_viz.core.rotations import euler_matrix
    from livox_viz.scene.raycast import EmbreeCaster, casting_in_this_thread

    x, y = np.meshgrid(np.linspace(-30.0, 30.0, 61), np.linspace(-30.0, 30.0, 61), indexing="ij")
    heights = 2.0 + 0.4 * np.sin(x / 3.0) * np.cos(y / 4.0)
    vertices = np.column_stack([x.ravel(), y.ravel(), heights.ravel()])
    corner = (np.arange(60)[:, None] * 61 + np.arange(60)[None, :]).ravel()
    faces = np.concatenate([np.column_stack([corner, corner + 61, corner + 1]),
                            np.column_stack([corner + 1, corner + 61, corner + 62])])
    objects = [trimesh.Trimesh(vertices, faces),
               trimesh.creation.box((1.0, 1.0, 3.0)).apply_translation((-6.0, 1.0, 0.0)),
               trimesh.creation.box((1.0, 1.0, 3.0)).apply_translation((0.5, 5.0, 0.0)),
               trimesh.creation.box((2.0, 2.0, 2.0)).apply_translation((-25.0, -3.0, 0.0)),
               trimesh.creation.icosphere(2, 0.7).apply_translation((1.0, -2.5, 0.6))]
    if sensor_in_a_box:
        # Half a millimetre in front of the sensor: its box, inflated by at least a millimetre, holds the sensor.
        objects.append(trimesh.creation.box((0.4, 0.4, 0.4)).apply_translation((0.2005, 0.0, 0.05)))
    mesh = trimesh.util.concatenate(objects)
    set_face_materials(mesh, np.full(len(mesh.faces), 0.5), np.ones(len(mesh.faces)),
                       np.repeat(np.arange(len(objects)), [len(o.faces) for o in objects]))
    rotation = euler_matrix(math.radians(10.0), math.radians(-25.0), math.radians(30.0))  # sensor FRD -> world
    origin = np.zeros((1, 3))
    rng = np.random.default_rng(11)
    around = rng.normal(size=(12000, 3))
    edge = np.column_stack([np.ones(8000), rng.uniform(-2.1, 2.1, (8000, 2))])
    edge[::2, 1 + rng.integers(0, 2, 4000)] = rng.choice([-1.0, 1.0], 4000) * rng.uniform(1.9, 2.0, 4000)
    sensor = np.concatenate([around, edge])
    sensor /= np.linalg.norm(sensor, axis=1, keepdims=True)
    world = sensor @ rotation.T
    with casting_in_this_thread():
        caster = EmbreeCaster(mesh)
        triangle = caster.triangle_ids(origin[0], world.astype(np.float32), 60.0).astype(np.int64)
        distance = caster.distances(origin[0], world.astype(np.float32), 60.0)
    reach = np.where(triangle >= 0, np.minimum(distance * 1.02 + 0.05, 60.0), 60.0)
    answers = []
    for grid in (True, False):
        proxy = TileProxy(mesh, math.tan(math.radians(0.14)))
        boxes = proxy.place(origin, 60.0, rotation if grid else None)
        assert (boxes[1] is not None) == grid
        if grid:
            assert boxes[1].always.size == int(sensor_in_a_box)  # only the box holding the sensor
        crossed = np.empty((len(world), 8), np.int64)
        near = proxy.near(np.ones(len(world), dtype=bool), origin, world, reach, triangle, sensor if grid else None,
                          boxes, crossed)
        answers.append((near, crossed))
    (near_grid, crossed_grid), (near_tree, crossed_tree) = answers
    np.testing.assert_array_equal(near_grid, near_tree)
    assert 0.02 * len(world) < near_grid.sum() < 0.9 * len(world)
    np.testing.assert_array_equal(crossed_grid[:, 0] == -2, crossed_tree[:, 0] == -2)
    listed = np.flatnonzero(crossed_grid[:, 0] != -2)
    assert listed.size > 1000
    def tiles(crossed: np.ndarray) -> set[int]:
        stop = np.flatnonzero(crossed == -1)
        return set(crossed[: stop[0] if stop.size else crossed.size].tolist())

    for row in listed:
        assert tiles(crossed_grid[row]) == tiles(crossed_tree[row]), row


def test_placing_again_from_the_same_pose_reuses_the_boxes_and_a_new_pose_files_them_anew() -> None:
    """A fixed sensor places its boxes every run: the same pose gets the same boxes back, without filing them
    again; a turned sensor gets those a fresh proxy files for its new rotation, and a moved one a sphere of
    positions (no grid), as if it had never been placed."""
    mesh = trimesh.util.concatenate([
        trimesh.creation.box((1.0, 1.0, 3.0)).apply_translation((8.0, 1.0, 0.0)),
        trimesh.creation.box((1.0, 1.0, 3.0)).apply_translation((6.0, -4.0, 0.0)),
        trimesh.creation.box((2.0, 2.0, 2.0)).apply_translation((-9.0, 3.0, 0.0))])
    set_face_materials(mesh, np.full(len(mesh.faces), 0.5), np.ones(len(mesh.faces)), np.repeat(np.arange(3), 12))
    tan_half = math.tan(math.radians(0.14))
    origin = np.array([0.5, 0.25, -1.0])
    ahead, turned = np.eye(3), np.array([[-1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]])  # yaw 180 deg

    def filed(boxes) -> tuple:
        grid = boxes[1]
        return grid.cell_start.tolist(), grid.cell_boxes.tolist(), grid.always.tolist()

    proxy = TileProxy(mesh, tan_half)
    first = proxy.place(origin, 60.0, ahead)
    assert proxy.place(origin.copy(), 60.0, ahead.copy()) == first  # the very same tree and grid
    assert first[1].cell_boxes.size > 0
    again = proxy.place(origin, 60.0, turned)
    assert again[1] is not first[1]
    assert filed(again) == filed(TileProxy(mesh, tan_half).place(origin, 60.0, turned))
    assert filed(again) != filed(first)  # the boxes ahead are behind it now, those behind ahead
    assert proxy.place(origin, 60.0, ahead)[1] is not again[1]
    moved = proxy.place(origin + 3.0, 60.0, ahead)
    assert moved[1] is None and moved[0] is not None  # a sensor that moved: a sphere of positions, no grid
