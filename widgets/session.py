"""The state behind the GUI, without VTK: configuration, playback clock, pattern and scan.

Parameters flow one way: a slider asks the session for a new configuration
(``set_param``); the session validates it, restarts the pattern and scanner
from it, and the views redraw from the session. Every array a view shows comes
from here, so the off-screen renderer and the tests see exactly what the
window shows.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import numpy as np

from livox_viz import LivoxVizError, ScanPattern, SensorConfig
from livox_viz.codec import decode_int16, encode_int16
from livox_viz.directions import directions_from_xy, xy_from_directions
from livox_viz.metrics import coverage
from livox_viz.pattern import PatternChunk
from livox_viz.poses import Pose
from livox_viz.reference import ReferencePattern
from livox_viz.rflysim import LivoxFrame
from livox_viz.scan import LidarScanner
from livox_viz.scene import Scene

from .ring import CoverageCounts, DensityGrid, PointRing

#: Integration windows a user can pick, seconds (None = unlimited, up to the ring's capacity).
WINDOWS: tuple[float | None, ...] = (0.1, 0.5, 1.0, 2.0, None)
#: Points the unlimited window holds at most.
UNLIMITED_POINTS = 1_000_000
SPEED_RANGE = (0.01, 10.0)
STEP_UNITS: tuple[str, ...] = ("arc", "petal", "figure-8", "flower", "frame")
PATTERN_COLOURS: tuple[str, ...] = ("time", "figure-8", "petal", "flower", "arc")
SCENE_COLOURS: tuple[str, ...] = ("range", "height", "time")
#: Most points one tick may add; a slow machine drops scan time rather than freezing.
MAX_POINTS_PER_TICK = 400_000


def window_label(window: float | None) -> str:
    """``"0.5 s"`` or ``"unlimited"``."""
    return "unlimited" if window is None else f"{window:g} s"


@dataclass
class Playback:
    """The playback clock: scan time advances ``speed`` times as fast as wall time unless paused.

    Parameters
    ----------
    speed : float
        Scan seconds per wall second, in [0.01, 10].
    paused : bool
    """

    speed: float = 1.0
    paused: bool = False
    _last_wall: float | None = field(default=None, repr=False)

    def set_speed(self, speed: float) -> float:
        """Set the speed, clipped into :data:`SPEED_RANGE`; returns the speed set."""
        if not math.isfinite(speed):
            raise LivoxVizError(f"speed {speed!r}; allowed: {SPEED_RANGE[0]} to {SPEED_RANGE[1]}")
        self.speed = float(min(max(speed, SPEED_RANGE[0]), SPEED_RANGE[1]))
        return self.speed

    def restart(self) -> None:
        """Forget the last tick's wall time, so a restart does not jump ahead."""
        self._last_wall = None

    def elapsed(self, now: float | None = None) -> float:
        """Scan seconds to add since the last call (0 when paused)."""
        now = time.monotonic() if now is None else now
        last, self._last_wall = self._last_wall, now
        if last is None or self.paused:
            return 0.0
        return max(0.0, now - last) * self.speed


class Session:
    """Pattern and scan state of the GUI.

    Parameters
    ----------
    config : SensorConfig
    scene : Scene
    seed : int
    preset_name : str
        Shown in the heads-up text and written to screenshot sidecars.
    vehicle_pose : Pose, optional
        Default: the scene's own.
    """

    def __init__(self, config: SensorConfig, scene: Scene, seed: int = 0, preset_name: str = "",
                 vehicle_pose: Pose | None = None) -> None:
        from livox_viz.raycast import EmbreeCaster

        self.scene = scene
        self.seed = seed
        self.preset_name = preset_name
        self.vehicle_pose = vehicle_pose or scene.vehicle_pose
        self.caster = EmbreeCaster(scene.mesh)
        self.playback = Playback()
        self.window_index = 1
        self.step_unit = "flower"
        self.pattern_colour = "time"
        #: Pattern view drawing: "auto" (a density image once the window holds more points than pixels),
        #: "points" or "density".
        self.pattern_drawing = "auto"
        self.scene_colour = "range"
        self.message = ""
        self.config = config
        self.reference: ReferencePattern | None = None
        self.source = None  # a receiver with poll() -> list of LivoxFrame, for listen --gui
        self._received_points = 0
        self.reference_window_index = 1
        self.reference_visible = True
        self.reference_ring = PointRing(1)
        self._reference_position = 0
        self._make_rings()
        self.restart(config)

    def set_scene(self, scene: Scene) -> None:
        """Cast into another scene (its own default vehicle pose) and restart the scan."""
        from livox_viz.raycast import EmbreeCaster

        caster = EmbreeCaster(scene.mesh)
        self.scene = scene
        self.caster = caster
        self.vehicle_pose = scene.vehicle_pose
        self.restart()

    # Reference overlay ------------------------------------------------------------------
    @property
    def reference_window(self) -> float | None:
        """Integration window of the reference overlay, seconds (None = unlimited)."""
        return WINDOWS[self.reference_window_index]

    def set_reference(self, reference: ReferencePattern | None) -> None:
        """Overlay a measured pattern, played in step with the scan (looping over its table)."""
        self.reference = reference
        self._make_reference_ring()
        self._reference_position = math.ceil(self.scan_time * reference.rate - 1e-9) if reference else 0

    def set_reference_window(self, index: int) -> None:
        """Pick the overlay's own integration window from :data:`WINDOWS`."""
        if not 0 <= index < len(WINDOWS):
            raise LivoxVizError(f"window index {index}; allowed: 0 to {len(WINDOWS) - 1}")
        self.reference_window_index = index
        self._make_reference_ring()

    def _make_reference_ring(self) -> None:
        if self.reference is None:
            self.reference_ring = PointRing(1)
            return
        window = self.reference_window
        capacity = UNLIMITED_POINTS if window is None else max(1, math.ceil(window * self.reference.rate))
        self.reference_ring = PointRing(capacity)
        start = 0.0 if window is None else max(0.0, self.scan_time - window)
        self._reference_position = math.ceil(start * self.reference.rate - 1e-9)
        self._add_reference(self.scan_time)

    def _add_reference(self, scan_time: float) -> None:
        reference = self.reference
        if reference is None:
            return
        target = math.ceil(scan_time * reference.rate - 1e-9)
        count = min(target - self._reference_position, self.reference_ring.capacity)
        if count <= 0:
            return
        first = target - count
        rows = np.arange(first, target) % reference.xy_deg.shape[0]
        xyz = np.zeros((count, 3), dtype=np.float32)
        xyz[:, :2] = reference.xy_deg[rows]
        times = np.arange(first, target) / reference.rate
        self.reference_ring.write(xyz, np.zeros(count, dtype=np.float32), times, np.arange(first, target))
        self._reference_position = target
        if self.reference_window is not None:
            self.reference_ring.drop_older_than(scan_time - self.reference_window)

    def reference_coverage(self) -> float | None:
        """FOV coverage of the overlay's points (its own FOV), or None without a reference."""
        if self.reference is None or self.reference_ring.count == 0:
            return None
        ring = self.reference_ring
        radius = float(self.reference.alpha_deg.max())
        return coverage(ring.positions[ring.live_slots(), :2].astype(np.float64), radius)

    # Configuration --------------------------------------------------------------------
    @property
    def window(self) -> float | None:
        """The integration window, seconds, or None for unlimited."""
        return WINDOWS[self.window_index]

    def restart(self, config: SensorConfig | None = None) -> None:
        """Start the pattern again from scan time 0, with ``config`` if given."""
        if config is not None:
            resize = config.point_rate != self.config.point_rate
            self.config = config
            if resize:
                self._make_rings()
        self.pattern = ScanPattern(self.config, seed=self.seed)
        self.scanner = LidarScanner(self.config, self.caster, self.vehicle_pose, seed=self.seed)
        self.scan_time = 0.0
        self.playback.restart()
        self.frame_index = 0
        if self.density.radius != self.config.half_fov_deg:
            self._make_counts()
        self.pattern_ring.clear()
        self.density.clear()
        self.coverage_counts.clear()
        self.scene_ring.clear()
        self.reference_ring.clear()
        self._reference_position = 0

    def set_param(self, name: str, value: float) -> bool:
        """Change one configuration field and restart; False (and a message) if the value is not allowed."""
        try:
            config = self.config.with_param(name, value)
        except LivoxVizError as exc:
            self.message = str(exc)
            return False
        self.message = ""
        if config != self.config:
            self.restart(config)
        return True

    def set_jitter_scope(self, scope: str) -> None:
        """Switch when the random rotation is added ("flower" or "figure") and restart."""
        self.restart(replace(self.config, jitter_scope=scope))

    def set_window(self, index: int) -> None:
        """Pick :data:`WINDOWS` ``[index]`` and resize the rings (keeps the scan time)."""
        if not 0 <= index < len(WINDOWS):
            raise LivoxVizError(f"window index {index}; allowed: 0 to {len(WINDOWS) - 1}")
        self.window_index = index
        self._make_rings()
        self.pattern_ring.clear()
        self.density.clear()
        self.coverage_counts.clear()
        self.scene_ring.clear()
        # Refill the new window from the stream so the picture stays continuous.
        self._refill()

    def _make_rings(self) -> None:
        window = self.window
        capacity = UNLIMITED_POINTS if window is None else max(1, math.ceil(window * self.config.point_rate))
        self.pattern_ring = PointRing(capacity)
        self.scene_ring = PointRing(capacity)
        self._make_counts()

    def _make_counts(self) -> None:
        """Density image and coverage cells of the pattern ring, kept in step with it."""
        self.density = DensityGrid(self.config.half_fov_deg)
        self.coverage_counts = CoverageCounts(self.config.half_fov_deg)

        def evicted(positions: np.ndarray) -> None:
            self.density.remove(positions)
            self.coverage_counts.remove(positions)

        self.pattern_ring.on_evict = evicted

    def _count_in(self, xyz: np.ndarray) -> None:
        kept = xyz[-self.pattern_ring.capacity :]
        self.density.add(kept)
        self.coverage_counts.add(kept)

    def _refill(self) -> None:
        start_time = 0.0 if self.window is None else max(0.0, self.scan_time - self.window)
        target = self.scan_time
        self.pattern = ScanPattern(self.config, seed=self.seed)
        self.pattern.skip(math.ceil(start_time * self.config.point_rate - 1e-9))
        self.scan_time = start_time
        self.advance_to(target)

    # Playback -------------------------------------------------------------------------
    def tick(self, now: float | None = None) -> int:
        """Advance by the wall time since the last tick; returns the points added.

        With a live :attr:`source` (``livox-viz listen --gui``) the frames that
        arrived are shown instead of the model's pattern.
        """
        if self.source is not None:
            if self.playback.paused:
                return 0
            return sum(self.add_received(frame) for frame in self.source.poll())
        return self.advance_to(self.scan_time + self.playback.elapsed(now))

    def add_received(self, frame: LivoxFrame) -> int:
        """Show a frame received from RflySim: its angles in the pattern view, its points in the scene."""
        decoded = frame.decoded(self.config.range_max)
        count = decoded.shape[0]
        ranges = np.linalg.norm(decoded, axis=1)
        safe = np.where(ranges > 0, ranges, 1.0)[:, None]
        xyz = np.zeros((count, 3), dtype=np.float32)
        xyz[:, :2] = xy_from_directions(decoded / safe)
        times = np.full(count, frame.timestamp)
        index = np.arange(self._received_points, self._received_points + count)
        self._received_points += count
        self.scan_time = frame.timestamp + 1.0 / self.config.data_check_freq
        self.frame_index = round(frame.timestamp * self.config.data_check_freq)
        self.pattern_ring.write(xyz, self.pattern_scalars(index, times), times, index)
        self._count_in(xyz)
        pose = Pose(tuple(frame.pos_ang[:3]), *frame.pos_ang[3:])
        world = pose.origin + decoded @ pose.rotation.T
        self.scene_ring.write(world, self.scene_scalars(world, ranges, times), times, index)
        self._drop_old()
        return count

    def advance_to(self, scan_time: float) -> int:
        """Emit (and cast) every point before ``scan_time`` seconds; returns how many."""
        rate = self.config.point_rate
        target = math.ceil(scan_time * rate - 1e-9)
        missing = target - self.pattern.position
        if missing > MAX_POINTS_PER_TICK:
            # Too far behind: jump, keeping only what the window can show.
            keep = min(self.pattern_ring.capacity, MAX_POINTS_PER_TICK)
            self.pattern.skip(missing - keep)
            missing = keep
        if missing <= 0:
            self.scan_time = max(self.scan_time, scan_time)
            return 0
        chunk = self.pattern.take(missing)
        self.scan_time = scan_time
        self._add_reference(scan_time)
        self._add_pattern(chunk)
        self._add_scan(chunk)
        self._drop_old()
        self.frame_index = (target - 1) // self.config.points_per_frame
        return missing

    def step(self, unit: str | None = None) -> int:
        """Advance to the next boundary of ``unit`` (default :attr:`step_unit`); returns the points added."""
        unit = unit or self.step_unit
        cfg = self.config
        size = {"arc": cfg.data_width, "petal": 2 * cfg.data_width, "figure-8": cfg.points_per_figure8,
                "flower": cfg.points_per_flower, "frame": cfg.points_per_frame}
        if unit not in size:
            raise LivoxVizError(f"step unit {unit!r}; allowed: {', '.join(STEP_UNITS)}")
        position = self.pattern.position
        boundary = (position // size[unit] + 1) * size[unit]
        return self.advance_to(boundary / cfg.point_rate)

    def _add_pattern(self, chunk: PatternChunk) -> None:
        xyz = np.zeros((len(chunk), 3), dtype=np.float32)
        xyz[:, :2] = chunk.xy_deg
        self.pattern_ring.write(xyz, self.pattern_scalars(chunk.index, chunk.t), chunk.t, chunk.index)
        self._count_in(xyz)

    def _add_scan(self, chunk: PatternChunk) -> None:
        """Cast the chunk's rays; the scene ring gets the decoded returns, placed in the world."""
        directions = directions_from_xy(chunk.xy_deg)
        ranges = self.scanner.cast_sensor_directions(directions)
        hit = np.isfinite(ranges)
        if not np.any(hit):
            return
        pose = self.scanner.sensor_pose
        sensor_points = directions[hit] * ranges[hit, None]
        decoded = decode_int16(encode_int16(sensor_points, self.config.range_max), self.config.range_max)
        world = pose.origin + decoded @ pose.rotation.T
        t = chunk.t[hit]
        self.scene_ring.write(world, self.scene_scalars(world, ranges[hit], t), t, chunk.index[hit])

    def _drop_old(self) -> None:
        if self.window is not None:
            limit = self.scan_time - self.window
            self.pattern_ring.drop_older_than(limit)
            self.scene_ring.drop_older_than(limit)

    # Colours --------------------------------------------------------------------------
    def pattern_scalars(self, stream_index: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Scalars of pattern points for the current colour mode, ``(n,)`` float32."""
        cfg = self.config
        mode = self.pattern_colour
        if mode == "time":
            return t.astype(np.float32)
        if mode == "figure-8":
            values = (stream_index // cfg.points_per_figure8) % cfg.figure8_per_flower
        elif mode == "petal":
            values = (stream_index // (2 * cfg.data_width)) % (2 * cfg.figure8_per_flower)
        elif mode == "flower":
            values = (stream_index // cfg.points_per_flower) % cfg.flowers_per_figure
        else:
            values = (stream_index // cfg.data_width) % 4
        return values.astype(np.float32)

    def pattern_scalar_range(self) -> tuple[float, float]:
        """Colour range of the pattern view for the current mode."""
        cfg = self.config
        mode = self.pattern_colour
        if mode == "time":
            low = self.scan_time - self.window if self.window is not None else 0.0
            return max(0.0, low), max(self.scan_time, 1e-6)
        top = {"figure-8": cfg.figure8_per_flower, "petal": 2 * cfg.figure8_per_flower,
               "flower": cfg.flowers_per_figure, "arc": 4}[mode]
        return 0.0, float(max(top - 1, 1))

    def scene_scalars(self, world: np.ndarray, ranges: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Scalars of scene points for the current colour mode, ``(n,)`` float32."""
        if self.scene_colour == "range":
            return ranges.astype(np.float32)
        if self.scene_colour == "height":
            return (-world[:, 2]).astype(np.float32)
        return t.astype(np.float32)

    def scene_scalar_range(self) -> tuple[float, float]:
        """Colour range of the scene view for the current mode."""
        if self.scene_colour == "range":
            return 0.0, min(self.config.range_max, 150.0)
        if self.scene_colour == "height":
            return 0.0, 30.0
        return self.pattern_scalar_range() if self.pattern_colour == "time" else (0.0, max(self.scan_time, 1e-6))

    def recolour(self) -> None:
        """Recompute all scalars after a colour mode change."""
        ring = self.pattern_ring
        live = ring.live_slots()
        ring.scalars[live] = self.pattern_scalars(ring.stream_index[live], ring.times[live])
        ring = self.scene_ring
        live = ring.live_slots()
        if ring.count:
            world = ring.positions[live].astype(np.float64)
            ranges = np.linalg.norm(world - self.scanner.sensor_pose.origin, axis=1)
            ring.scalars[live] = self.scene_scalars(world, ranges, ring.times[live])

    # Measures -------------------------------------------------------------------------
    def visible_coverage(self) -> float:
        """FOV coverage of the points the pattern view shows (5 mrad cells), kept up to date per point."""
        return self.coverage_counts.coverage()
