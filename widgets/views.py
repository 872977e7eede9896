"""The two linked views: the pattern in the angular plane, and the scan cast into the 3D scene.

Each view adds its actors once and afterwards only marks the ring's arrays
modified and re-points its vertex cells at the live slots (see
:class:`~livox_viz.widgets.ring.PointRing`): no actor is re-created on a tick.
Each view subscribes to the session and redraws what depends on the
configuration, the scene or the vehicle pose whenever one of them changes.
"""

from __future__ import annotations

import math

import numpy as np
import pyvista as pv

from livox_viz.core.rotations import FRD_TO_FLU

from .ring import PointRing
from .session import TAG_CLASSES, Session

#: NED (z down) to the display's z-up frame (north-west-up), as a 4x4 actor matrix.
NED_TO_DISPLAY = np.eye(4)
NED_TO_DISPLAY[:3, :3] = FRD_TO_FLU
PATTERN_UNITS = {"time": "time, s", "figure-8": "figure-8 in flower", "petal": "petal in flower",
                 "flower": "flower in figure", "arc": "arc in figure-8", "laser": "laser"}
SCENE_UNITS = {"range": "range, m", "height": "height, m", "time": "time, s",
               "reflectivity": "reflectivity",
               "return/tag": "return / tag"}
#: Marks of the reflectivity bar: the byte of a 10 %, 50 % and white Lambertian target (0-150 is 0-100 %) and the
#: top of the retroreflective bytes (151-255), not a log scale's ticks (1, 4, 16, 63.8, 255), which mean nothing.
REFLECTIVITY_MARKS = {1.0: "1", 15.0: "15  10 %", 75.0: "75  50 %", 150.0: "150  white", 255.0: "255  retro"}
#: Colours of the return/tag classes (return 0, 1, 2, 3, mixed, noise).
TAG_COLOURS = ("#9aa5b1", "#4fc3f7", "#ffb74d", "#ba68c8", "#ff5252", "#fff176")


def ring_polydata(ring: PointRing) -> pv.PolyData:
    """A PolyData sharing the ring's point and scalar arrays (zero copy), one vertex per live point."""
    poly = pv.PolyData()
    poly.points = ring.positions
    poly.point_data.set_array(ring.scalars, "scalars")
    poly.point_data.active_scalars_name = "scalars"
    update_ring_polydata(poly, ring)
    return poly


def update_ring_polydata(poly: pv.PolyData, ring: PointRing, stride: int = 1) -> None:
    """Tell VTK the ring changed: re-point the vertex cells if the live slots moved, mark the arrays modified.

    A full ring draws every slot, in any order, so its cells stay the same
    from tick to tick and VTK does not rebuild its index buffer. With
    ``stride`` k > 1 only the slots that are multiples of k are drawn (a level
    of detail): always the same slots, so the thinned cloud does not shimmer
    as the ring turns.
    """
    if poly.GetPoints().GetData().GetVoidPointer(0) != _address(ring.positions):
        poly.points = ring.positions
        poly.point_data.set_array(ring.scalars, "scalars")
        poly.point_data.active_scalars_name = "scalars"
    full = ring.count == ring.capacity
    cells_key = (id(ring), "full", stride) if full else (id(ring), ring.tail, ring.count, stride)
    if getattr(poly, "_livox_cells_key", None) != cells_key:
        slots = ring.all_slots() if full else ring.live_slots()
        if stride > 1:
            slots = np.ascontiguousarray(slots[(-ring.tail if not full else 0) % stride :: stride])
        poly.SetVerts(pv.CellArray.from_arrays(ring.cell_offsets()[: slots.size + 1], slots))
        poly._livox_cells_key = cells_key
    poly.GetPoints().GetData().Modified()
    poly.GetPoints().Modified()
    poly.GetPointData().GetArray("scalars").Modified()
    poly.Modified()


#: Points of the scene's cloud drawn at most, unless the drawing is "points": software GL takes about 0.45 ms
#: per thousand points (bench_window.py), so a million drawn cost 450 ms a frame, a quarter of a million 180 ms.
SCENE_DRAW_LIMIT = 250_000


def lod_stride(count: int, limit: int) -> int:
    """Every how many points to draw so that at most ``limit`` of ``count`` are drawn."""
    return max(1, -(-count // limit))


def one_mesh(parts: list[pv.PolyData]) -> pv.PolyData:
    """Line meshes as one mesh, their points and line cells joined with numpy.

    What the guides and the FOV wire are made of: one actor instead of a dozen, and no ``merge`` filter
    (merging and adding them one by one took 65 ms of every change of field of view).
    """
    points, offsets, connectivity, start, end = [], [np.zeros(1, dtype=np.int64)], [], 0, 0
    for part in parts:
        if part.n_points == 0:
            continue
        lines = part.GetLines()
        points.append(np.asarray(part.points, dtype=np.float64))
        connectivity.append(pv.convert_array(lines.GetConnectivityArray()).astype(np.int64) + start)
        offsets.append(pv.convert_array(lines.GetOffsetsArray()).astype(np.int64)[1:] + end)
        start += part.n_points
        end += connectivity[-1].size
    mesh = pv.PolyData()
    if points:
        mesh.points = np.vstack(points)
        mesh.lines = pv.CellArray.from_arrays(np.concatenate(offsets), np.concatenate(connectivity))
    return mesh


def _address(array: np.ndarray) -> int:
    return int(array.__array_interface__["data"][0])


def add_scalar_bar(plotter: pv.Plotter, title: str, mapper) -> object:
    """The vertical colour bar both views show at their right edge."""
    return plotter.add_scalar_bar(
        title, mapper=mapper, vertical=True, position_x=0.9, position_y=0.2, width=0.05, height=0.6,
        title_font_size=12, label_font_size=11, color="#dde3ea", n_labels=5, fmt="%.3g",
    )


class _View:
    """What both views share: the plotter, the session, and their own renderer in the window.

    Parameters
    ----------
    plotter : pyvista.Plotter
    session : Session
    subplot : tuple of int
        Where the view lives in the plotter.
    """

    background: tuple[str, str | None] = ("#10141c", None)

    def __init__(self, plotter: pv.Plotter, session: Session, subplot: tuple[int, int]) -> None:
        self.plotter = plotter
        self.session = session
        self.subplot = subplot
        plotter.subplot(*subplot)
        self.renderer = plotter.renderer
        plotter.set_background(self.background[0], top=self.background[1])


class PatternView(_View):
    """The angular plane in degrees: FOV circle, degree rings, the live pattern (or its density image)."""

    def __init__(self, plotter: pv.Plotter, session: Session, subplot: tuple[int, int]) -> None:
        super().__init__(plotter, session, subplot)
        self._guides: list = []
        self._guide_actors: tuple | None = None
        self._ring = session.pattern_ring
        self.poly = ring_polydata(self._ring)
        self.actor = plotter.add_mesh(
            self.poly, scalars="scalars", cmap="turbo", point_size=2.0, render_points_as_spheres=False,
            show_scalar_bar=False, name="pattern", reset_camera=False, lighting=False,
        )
        self._reference_ring = session.overlay.ring
        self.reference_poly = ring_polydata(self._reference_ring)
        self.reference_actor = plotter.add_mesh(
            self.reference_poly, color="#f5f7fa", opacity=0.55, point_size=1.5, render_points_as_spheres=False,
            name="reference", reset_camera=False, lighting=False, scalars=None,
        )
        self.scalar_bar = add_scalar_bar(plotter, PATTERN_UNITS[session.display.pattern_colour], self.actor.mapper)
        self._density_grid = None
        self.density_actor = None
        self._guides_fov = None
        self._make_density_image()
        self.draw_guides()
        self.reset_camera()
        session.subscribe(self._on_change)

    def _on_change(self, what: str) -> None:
        # The guides are drawn from the FOV alone: redrawn (and the camera refitted) when it changed.
        if what == "config" and self._guides_fov != self.session.config.field_of_view:
            self.draw_guides()
            self.reset_camera()

    def _make_density_image(self) -> None:
        """The density image of the window's points (shown instead of the points when they outnumber pixels)."""
        grid = self.session.density
        if grid is self._density_grid:
            return
        self._density_grid = grid
        # A texture on one quad: software GL draws it far faster than a cell per pixel.
        image = pv.ImageData(dimensions=(grid.nx, grid.ny, 1))
        image.point_data.set_array(grid.display, "density")
        image.point_data.active_scalars_name = "density"
        self.density_image = image
        x0, x1, y0, y1 = grid.bounds
        quad = pv.Plane(center=((x0 + x1) / 2, (y0 + y1) / 2, -0.01), direction=(0, 0, 1),
                        i_size=grid.nx * grid.cell, j_size=grid.ny * grid.cell, i_resolution=1, j_resolution=1)
        if self.density_actor is not None:
            # Another grid (the field of view changed): the same texture, lookup table and actor, new image and quad.
            self.density_texture.SetInputData(image)
            self.density_actor.mapper.SetInputData(quad)
            return
        self.density_lut = pv.LookupTable(cmap="inferno", n_values=256)
        self.density_lut.scalar_range = (0.0, 1.0)
        colours = np.array(self.density_lut.values)
        colours[0] = (16, 20, 28, 255)  # empty cells in the view's background colour
        self.density_lut.values = colours
        texture = pv.Texture()
        texture.SetInputData(image)
        texture.SetLookupTable(self.density_lut)
        texture.SetColorModeToMapScalars()
        # Linear filtering and mipmaps: a one-texel trace must not vanish when the image is shrunk.
        texture.InterpolateOn()
        texture.MipmapOn()
        self.density_texture = texture
        self.plotter.subplot(*self.subplot)
        self.density_actor = self.plotter.add_mesh(quad, texture=texture, name="density", reset_camera=False,
                                                   lighting=False, show_scalar_bar=False)
        self.density_actor.SetVisibility(False)

    def density_shown(self) -> bool:
        """Whether the view draws the density image rather than the points."""
        mode = self.session.display.drawing
        if mode != "auto":
            return mode == "density"
        width, height = self.renderer.GetSize()
        return self.session.pattern_ring.count > max(width * height, 1)

    def draw_guides(self) -> None:
        """The field of view's outline, a degree grid, cross hairs, and the axis names.

        The boresight plane gets rings of equal angle off the boresight (kept to the field of view's box);
        the panorama plane gets lines of azimuth and elevation.
        """
        plotter = self.plotter
        plotter.subplot(*self.subplot)
        if "grid-labels" in self._guides:
            plotter.remove_actor("grid-labels", render=False)
        self._guides = []
        fov = self.session.config.field_of_view
        self._guides_fov = fov
        grid_lines, labels, positions = (_panorama_grid(fov) if fov.plane == "panorama" else _boresight_grid(fov))
        # The grid and the outline are one mesh each, handed to the same two actors on every change.
        grid = one_mesh(grid_lines)
        boundary = fov.boundary()
        outline = pv.lines_from_points(np.column_stack([boundary, np.zeros(len(boundary))]))
        if self._guide_actors is None:
            self._guide_actors = (
                plotter.add_mesh(grid, color="#3a4454", line_width=1, name="grid", reset_camera=False,
                                 lighting=False, pickable=False),
                plotter.add_mesh(outline, color="#f2c14e", line_width=2, name="fov-outline", reset_camera=False,
                                 lighting=False, pickable=False),
            )
        else:
            for actor, mesh in zip(self._guide_actors, (grid, outline), strict=True):
                actor.mapper.SetInputData(mesh)
        if labels:
            plotter.add_point_labels(positions, labels, font_size=11, text_color="#8a96a8", shape=None,
                                     show_points=False, name="grid-labels", always_visible=True, reset_camera=False)
            self._guides.append("grid-labels")
        x0, x1, y0, y1 = fov.bounds
        names = ["azimuth, right", "elevation"] if fov.plane == "panorama" else ["x right", "y up"]
        centre_x = 0.0 if x0 < 0 < x1 else (x0 + x1) / 2
        below = y0 - 0.3 * (y1 - y0) if fov.plane == "panorama" else (0.0 if y0 < 0 < y1 else y0) - 0.04 * (y1 - y0)
        plotter.add_point_labels(
            [(x1 - (0.2 if fov.plane == "panorama" else -0.01) * (x1 - x0), below, 0),
             (centre_x + 0.01 * (x1 - x0), y1 + 0.02 * (y1 - y0), 0)],
            names, font_size=11, text_color="#8a96a8", shape=None, show_points=False, name="axis-labels",
            always_visible=True, reset_camera=False,
        )
        self._guides.append("axis-labels")

    def reset_camera(self) -> None:
        """Look straight at the pattern plane, orthographic, the field of view filling the view."""
        x0, x1, y0, y1 = self.session.config.field_of_view.bounds
        half_width, half_height = (x1 - x0) / 2, (y1 - y0) / 2
        width, height = self.renderer.GetSize()
        camera = self.renderer.camera
        camera.enable_parallel_projection()
        # The FOV and its labels fit across as well as up, with the colour bar's strip on the right free.
        centre = ((x0 + x1) / 2 + half_width * 0.12, (y0 + y1) / 2 + half_height * 0.03)
        camera.focal_point = (*centre, 0)
        camera.position = (*centre, max(half_width, half_height) * 10)
        camera.up = (0, 1, 0)
        camera.parallel_scale = max(half_height * 1.18, half_width * 1.32 * height / max(width, 1))
        self.renderer.ResetCameraClippingRange()

    def update(self) -> None:
        """Show the ring's current points and colours."""
        if self._ring is not self.session.pattern_ring:
            self._ring = self.session.pattern_ring
        self._make_density_image()
        density = self.density_shown()
        self.actor.SetVisibility(not density)
        self.density_actor.SetVisibility(density)
        if density:
            display = self.session.density.refresh_display()
            self.density_image.GetPointData().GetArray("density").Modified()
            # Saturate at four times the mean of the occupied cells: the centre's pile-up would
            # otherwise leave everything else dark.
            counts = self.session.density.counts
            occupied = max(int(np.count_nonzero(counts)), 1)
            top = min(float(display.max()), math.log1p(4.0 * float(counts.sum()) / occupied))
            self.density_lut.scalar_range = (0.0, max(top, 1e-6))
            self.density_lut.annotations = count_marks(top)
            self.density_texture.Modified()
        bar_table = self.density_lut if density else self.actor.mapper.lookup_table
        if self.scalar_bar.GetLookupTable() is not bar_table:
            self.scalar_bar.SetLookupTable(bar_table)
        # The density's colours are log(1 + count): the bar is marked with counts, not those logarithms.
        self.scalar_bar.SetNumberOfLabels(0 if density else 5)
        self.scalar_bar.SetDrawAnnotations(density)
        update_ring_polydata(self.poly, self._ring)
        overlay = self.session.overlay
        self._reference_ring = overlay.ring
        update_ring_polydata(self.reference_poly, self._reference_ring)
        self.reference_actor.SetVisibility(overlay.source is not None and overlay.visible)
        low, high = self.session.pattern_scalar_range()
        self.actor.mapper.scalar_range = (low, high if high > low else low + 1e-6)
        self.scalar_bar.SetTitle("points/cell" if density else PATTERN_UNITS[self.session.display.pattern_colour])


def count_marks(top: float) -> dict[float, str]:
    """Marks of a colour bar of log(1 + count) from 0 to ``top``: the counts 0, 1, 2, 5, 10, 20, 50, ... it spans
    (1, 10, 100, ... only, when those would be more than seven), each at its log(1 + count)."""
    counts = [0] + [m * 10**k for k in range(9) for m in (1, 2, 5) if math.log1p(m * 10**k) <= top + 1e-9]
    if len(counts) > 7:
        counts = [c for c in counts if c == 0 or str(c).strip("0") == "1"]
    return {math.log1p(c): f"{c:,}" for c in counts}


def _ring_step(radius: float) -> float:
    """Spacing of the degree rings: about five rings across the FOV, at 1-2-5 steps."""
    raw = radius / 4.0
    magnitude = 10 ** math.floor(math.log10(raw))
    for factor in (1, 2, 5, 10):
        if raw <= factor * magnitude:
            return factor * magnitude
    return 10 * magnitude


def _boresight_grid(fov) -> tuple[list[pv.PolyData], list[str], list[tuple[float, float, float]]]:
    """Rings of equal angle off the boresight, kept inside the field of view's box, with their labels."""
    x0, x1, y0, y1 = fov.bounds
    reach = fov.reach_deg
    step = _ring_step(reach)
    margin = 0.04 * max(x1 - x0, y1 - y0)
    lines, labels, positions = [], [], []
    for ring_radius in np.arange(step, reach + 1e-9, step):
        angle = np.linspace(0.0, 2 * math.pi, 361)
        points = np.column_stack([ring_radius * np.cos(angle), ring_radius * np.sin(angle), np.zeros(angle.size)])
        inside = ((points[:, 0] >= x0 - margin) & (points[:, 0] <= x1 + margin)
                  & (points[:, 1] >= y0 - margin) & (points[:, 1] <= y1 + margin))
        for run in _runs(inside):
            if run.size > 1:
                lines.append(pv.lines_from_points(points[run]))
        label_at = (ring_radius * math.cos(math.radians(60)), ring_radius * math.sin(math.radians(60)), 0.0)
        if x0 <= label_at[0] <= x1 and y0 <= label_at[1] <= y1:
            labels.append(f"{ring_radius:g}°")
            positions.append(label_at)
    lines += [pv.Line((x0, 0, 0), (x1, 0, 0)), pv.Line((0, y0, 0), (0, y1, 0))]
    return lines, labels, positions


def _panorama_grid(fov) -> tuple[list[pv.PolyData], list[str], list[tuple[float, float, float]]]:
    """Lines of azimuth every 30 degrees and of elevation every 10 across the band, with their labels."""
    _, _, low, high = fov.bounds
    lines, labels, positions = [], [], []
    for azimuth in range(-150, 181, 30):
        lines.append(pv.Line((azimuth, low, 0), (azimuth, high, 0)))
        if azimuth % 90 == 0:
            labels.append(f"{azimuth}°")
            positions.append((azimuth + 2.0, low - 0.12 * (high - low), 0.0))
    step = _ring_step((high - low) * 1.5)
    for elevation in np.arange(math.ceil(low / step) * step, high + 1e-9, step):
        lines.append(pv.Line((-180, elevation, 0), (180, elevation, 0)))
        labels.append(f"{elevation:g}°")
        positions.append((-178.0, elevation + 0.02 * (high - low), 0.0))
    return lines, labels, positions


def _runs(mask: np.ndarray) -> list[np.ndarray]:
    """Index runs where ``mask`` holds."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return [np.arange(a, b) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def quadrotor_mesh(size: float = 0.5) -> pv.PolyData:
    """A small quadrotor in its body FRD frame (metres): body, four arms, four rotor discs."""
    parts = [pv.Box(bounds=(-0.12 * size, 0.12 * size, -0.08 * size, 0.08 * size, -0.05 * size, 0.05 * size))]
    for angle in (45, 135, 225, 315):
        direction = np.array([math.cos(math.radians(angle)), math.sin(math.radians(angle)), 0.0])
        tip = direction * 0.35 * size
        parts.append(pv.Cylinder(center=tip / 2, direction=direction, radius=0.015 * size, height=0.35 * size))
        rotor = tip + np.array([0.0, 0.0, -0.04 * size])
        parts.append(pv.Disc(center=rotor, inner=0.0, outer=0.14 * size, normal=(0, 0, 1)))
    merged = parts[0]
    for part in parts[1:]:
        merged = merged.merge(part)
    return merged


def fov_wire(fov, length: float = 1.6) -> pv.PolyData:
    """The field of view as a wire in the sensor frame FRD: its outline's rays at ``length`` and spokes.

    A boresight field of view is its outline's rim with eight rays from the apex; a panoramic band is
    its two rims (lowest and highest elevation) joined by eight meridians, with eight rays to the top rim.
    A translucent surface would hide the cloud behind it and push VTK into its slower translucent pass.
    """
    from livox_viz.patterns.planes import directions_from_xy

    if fov.plane == "panorama":
        low, high = fov.elevation_deg
        azimuth = np.linspace(-180.0, 180.0, 145)
        parts = []
        for elevation in (low, high):
            rim = directions_from_xy(np.column_stack([azimuth, np.full(azimuth.size, elevation)]), "panorama")
            parts.append(pv.lines_from_points(rim * length))
        for spoke in np.arange(-180.0, 180.0, 45.0):
            meridian = np.column_stack([np.full(20, spoke), np.linspace(low, high, 20)])
            arc = directions_from_xy(meridian, "panorama") * length
            parts += [pv.lines_from_points(arc), pv.Line((0.0, 0.0, 0.0), arc[-1])]
        return one_mesh(parts)
    boundary = fov.boundary(96)
    rim = directions_from_xy(boundary, "boresight") * length
    parts = [pv.lines_from_points(rim)]
    parts += [pv.Line((0.0, 0.0, 0.0), rim[k]) for k in np.linspace(0, len(rim) - 1, 9)[:-1].astype(int)]
    return one_mesh(parts)


class SceneView(_View):
    """The 3D scene (z up on screen), the vehicle, the sensor with its FOV cone, and the decoded cloud."""

    background = ("#1a1f29", "#3b4a63")

    def __init__(self, plotter: pv.Plotter, session: Session, subplot: tuple[int, int]) -> None:
        super().__init__(plotter, session, subplot)
        self._scene_shown = None
        self.draw_scene()
        self._ring = session.scene_ring
        self.poly = ring_polydata(self._ring)
        self.actor = plotter.add_mesh(
            self.poly, scalars="scalars", cmap="viridis", point_size=2.5, render_points_as_spheres=False,
            show_scalar_bar=False, name="cloud", reset_camera=False, lighting=False,
        )
        self.actor.user_matrix = NED_TO_DISPLAY
        self.scalar_bar = add_scalar_bar(plotter, SCENE_UNITS[session.display.scene_colour], self.actor.mapper)
        self.draw_vehicle()
        self.reset_camera()
        session.subscribe(self._on_change)

    def _on_change(self, what: str) -> None:
        """Anything the vehicle, the sensor or its cone depend on may have changed: draw them again."""
        if what == "scene":
            self.draw_scene()
        self.draw_vehicle()
        if what == "scene":
            self.reset_camera()

    def draw_scene(self) -> None:
        """The scene's triangles (again, when the session's scene changed)."""
        if self._scene_shown is self.session.scene:
            return
        self._scene_shown = self.session.scene
        self.plotter.subplot(*self.subplot)
        self.scene_actor = self.plotter.add_mesh(pv.wrap(self.session.scene.mesh), color="#717d90",
                                                 smooth_shading=False, name="scene", reset_camera=False)
        self.scene_actor.user_matrix = NED_TO_DISPLAY

    def draw_vehicle(self) -> None:
        """The vehicle at its pose, the sensor and a wire cone of the FOV along its boresight.

        The shapes are made once in their own frames (the cone again only when the FOV changes);
        a change of pose only moves them.
        """
        plotter = self.plotter
        plotter.subplot(*self.subplot)
        if "vehicle" not in plotter.actors:
            plotter.add_mesh(quadrotor_mesh(), color="#e8eef5", name="vehicle", reset_camera=False)
            plotter.add_mesh(pv.Sphere(radius=0.06), color="#f2c14e", name="sensor", reset_camera=False)
        fov = self.session.config.field_of_view
        if getattr(self, "_cone_fov", None) != fov:
            self._cone_fov = fov
            if "fov-cone" in plotter.actors:  # the same actor, a new wire: no remove and add
                plotter.actors["fov-cone"].mapper.SetInputData(fov_wire(fov))
            else:
                plotter.add_mesh(fov_wire(fov), color="#f2c14e", line_width=2, name="fov-cone", reset_camera=False,
                                 lighting=False)
        self.place_vehicle()
        self.draw_path()

    def place_vehicle(self) -> None:
        """Move the vehicle, the sensor and the cone to their poses at the current scan time.

        The camera follows the vehicle (moved by as much as it moved), keeping the user's angle and zoom.
        """
        actors = self.plotter.actors
        vehicle = self.session.vehicle_pose_now
        actors["vehicle"].user_matrix = NED_TO_DISPLAY @ vehicle.matrix
        for name in ("sensor", "fov-cone"):
            actors[name].user_matrix = NED_TO_DISPLAY @ self.session.sensor_pose.matrix
        here = NED_TO_DISPLAY[:3, :3] @ vehicle.origin
        followed = getattr(self, "_followed", None)
        if followed is not None and not np.array_equal(here, followed):
            camera = self.renderer.camera
            camera.position = tuple(np.array(camera.position) + here - followed)
            camera.focal_point = tuple(np.array(camera.focal_point) + here - followed)
            self.renderer.ResetCameraClippingRange()
        self._followed = here

    def draw_path(self) -> None:
        """The trajectory's path as a line (once per trajectory); nothing for a vehicle that stays."""
        trajectory = self.session.trajectory
        if trajectory is None or getattr(self, "_path_of", None) is trajectory:
            return
        self._path_of = trajectory
        stride = max(1, trajectory.t.size // 2000)
        path = pv.lines_from_points(np.asarray(trajectory.position[::stride]))
        self.plotter.subplot(*self.subplot)
        actor = self.plotter.add_mesh(path, color="#7fd3ff", line_width=2, name="path", reset_camera=False,
                                      lighting=False)
        actor.user_matrix = NED_TO_DISPLAY

    def reset_camera(self) -> None:
        """Behind and above the vehicle, looking along the sensor's boresight."""
        sensor = self.session.sensor_pose
        boresight = sensor.rotation @ np.array([1.0, 0.0, 0.0])
        flat = np.array([boresight[0], boresight[1], 0.0])
        flat = flat / np.linalg.norm(flat) if np.linalg.norm(flat) > 1e-6 else np.array([1.0, 0, 0])
        eye_ned = sensor.origin - flat * 9.0 + np.array([0, 0, -4.5])
        target_ned = sensor.origin + flat * 25.0 + np.array([0, 0, 1.0])
        to_display = NED_TO_DISPLAY[:3, :3]
        camera = self.renderer.camera
        camera.disable_parallel_projection()
        camera.position = tuple(to_display @ eye_ned)
        camera.focal_point = tuple(to_display @ target_ned)
        camera.up = (0, 0, 1)
        camera.view_angle = 50
        self.renderer.ResetCameraClippingRange()

    def _use_table(self, mode: str) -> None:
        """The colour table of a scene colour mode: classes for return/tag, log-scaled for reflectivity."""
        if mode == "return/tag":
            table = pv.LookupTable(cmap=list(TAG_COLOURS), n_values=len(TAG_COLOURS))
            table.annotations = dict(enumerate(TAG_CLASSES))
        else:
            table = pv.LookupTable(cmap="viridis", n_values=256)
            if mode == "reflectivity":
                # 1-255 logarithmically: dark asphalt at grazing incidence, paint and walls, signs.
                table.log_scale = True
                table.annotations = REFLECTIVITY_MARKS
        annotated = mode in ("return/tag", "reflectivity")
        self.actor.mapper.lookup_table = table
        self.scalar_bar.SetLookupTable(table)
        self.scalar_bar.SetNumberOfLabels(0 if annotated else 5)
        self.scalar_bar.SetDrawAnnotations(annotated)
        self.scalar_bar.GetAnnotationTextProperty().SetColor(0.87, 0.89, 0.92)

    def stride(self) -> int:
        """Every how many of the cloud's points are drawn: all with the "points" drawing, else at most
        :data:`SCENE_DRAW_LIMIT` (the ring's capacity decides, so the stride stays put while the window fills)."""
        if self.session.display.drawing == "points":
            return 1
        return lod_stride(self.session.scene_ring.capacity, SCENE_DRAW_LIMIT)

    def update(self) -> None:
        """Show the ring's current points and colours, and the vehicle where it is now."""
        if self.session.trajectory is not None:
            self.place_vehicle()
        if self._ring is not self.session.scene_ring:
            self._ring = self.session.scene_ring
        update_ring_polydata(self.poly, self._ring)
        mode = self.session.display.scene_colour
        if getattr(self, "_colour_mode", None) != mode:
            self._colour_mode = mode
            self._use_table(mode)

        update_ring_polydata(self.poly, self._ring, self.stride())
        low, high = self.session.scene_scalar_range()
        self.actor.mapper.scalar_range = (low, high if high > low else low + 1e-6)
        self.scalar_bar.SetTitle(SCENE_UNITS[mode])
