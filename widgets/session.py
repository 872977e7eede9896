"""The state behind the GUI, without VTK: configuration, scene, pattern, cast cloud and their rings.

Parameters flow one way: a slider asks the session for a new configuration
(:meth:`Session.set_param`); the session validates it, restarts the pattern
and the caster from it, and tells every listener what changed
(:meth:`Session.subscribe`); the views redraw whatever depends on it. Every
array a view shows comes from here, so the off-screen renderer and the tests
see exactly what the window shows.

The cloud is made by the model's one casting path
(:class:`~livox_viz.casting.scan.MountedCaster`), the same that ``livox-viz scan``
writes, and placed in the world with the frame's pose.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from livox_viz import LivoxVizError, SensorConfig
from livox_viz.casting.point_frame import PointFrame
from livox_viz.casting.scan import MountedCaster
from livox_viz.config.sensor import SERIES_MODELS
from livox_viz.core.poses import Pose
from livox_viz.core.workload import WINDOW_BUDGET, check_points
from livox_viz.motion.trajectory import Trajectory
from livox_viz.patterns.factory import make_pattern
from livox_viz.patterns.stream import PatternChunk, points_before
from livox_viz.scene.raycast import EmbreeCaster, RayCaster
from livox_viz.scene.scenes import Scene
from livox_viz.wire.received import ReceivedFrame

from .history import ConfigHistory, ConfigState, describe_change
from .live import LiveStats
from .overlay import WINDOWS, ReferenceOverlay, window_capacity
from .playback import Playback
from .ring import CoverageCounts, DensityGrid, PointRing

#: The integration window a session starts with (an index of :data:`~widgets.overlay.WINDOWS`).
FIRST_WINDOW = 1
#: The integration windows a user may type, seconds (besides unlimited).
WINDOW_RANGE = (0.01, 10.0)


def check_window(config: SensorConfig, window: float | None = WINDOWS[FIRST_WINDOW]) -> None:
    """Refuse a configuration whose pattern the integration window (seconds; None = unlimited) cannot hold
    (:data:`WINDOW_BUDGET`)."""
    check_points(window_capacity(window, config.point_rate), "the integration window", WINDOW_BUDGET)


def check_window_seconds(seconds: float | None) -> float | None:
    """An integration window a user typed: None (unlimited) or a finite number of seconds in :data:`WINDOW_RANGE`.

    Raises
    ------
    LivoxVizError
        Naming the value and the allowed range.
    """
    if seconds is None:
        return None
    if not (isinstance(seconds, (int, float)) and math.isfinite(seconds)
            and WINDOW_RANGE[0] <= seconds <= WINDOW_RANGE[1]):
        raise LivoxVizError(f"integration window {seconds!r} s; allowed: {WINDOW_RANGE[0]:g} to {WINDOW_RANGE[1]:g} s, "
                            "or unlimited")
    return float(seconds)

#: The units a step can advance by, as the user names them, and the stream unit behind each.
STEP_UNITS: dict[str, str] = {"arc": "arc", "petal": "petal", "figure-8": "figure8", "flower": "flower",
                              "frame": "frame"}
#: Pattern colour modes and the unit whose number (within the next larger unit) each shows.
PATTERN_COLOURS: dict[str, tuple[str, str] | None] = {
    "time": None, "figure-8": ("figure8", "flower"), "petal": ("petal", "flower"),
    "flower": ("flower", "figure"), "arc": ("arc", "figure8"), "laser": None,
}
SCENE_COLOURS: tuple[str, ...] = ("range", "height", "time", "reflectivity", "return/tag")
#: The categories of the return/tag colouring: each point's class from its Livox tag.
TAG_CLASSES: tuple[str, ...] = ("return 0", "return 1", "return 2", "return 3", "mixed", "noise")
CLOUD_FRAMES: tuple[str, ...] = ("world", "sensor")
DRAWINGS: tuple[str, ...] = ("auto", "points", "density")
#: Most points one tick may add; a slow machine drops scan time rather than freezing.
MAX_POINTS_PER_TICK = 400_000


@dataclass
class DisplayOptions:
    """How the views draw: colour modes, the pattern drawing and the step unit.

    Parameters
    ----------
    pattern_colour : str
        A key of :data:`PATTERN_COLOURS`.
    scene_colour : str
        One of :data:`SCENE_COLOURS`.
    drawing : str
        Pattern view: ``"auto"`` (a density image once the window holds more
        points than the view has pixels), ``"points"`` or ``"density"``.
    step_unit : str
        A key of :data:`STEP_UNITS`.
    cloud_frame : {"world", "sensor"}
        How a moving sensor's cloud accumulates: each point placed with the pose of its own
        time (a static wall stays sharp), or as the sensor sees it, placed with the pose at the
        end of its chunk (the smear of the motion shows).
    scene_colour_ranges : dict
        The colour ranges the user fixed (View > Colour range), by scene colouring: ``(low, high)`` in its unit;
        a colouring not in it spans the data's range.
    """

    pattern_colour: str = "time"
    scene_colour: str = "range"
    drawing: str = "auto"
    step_unit: str = "flower"
    cloud_frame: str = "world"
    scene_colour_ranges: dict[str, tuple[float, float]] = field(default_factory=dict)


def tag_classes(tag: np.ndarray) -> np.ndarray:
    """``(n,)`` float32 the :data:`TAG_CLASSES` index of Livox tags: noise, else mixed, else the return number."""
    tag = np.asarray(tag, dtype=np.uint8)
    out = ((tag >> 4) & 0x03).astype(np.float32)
    out[(tag & 0x03) != 0] = 4.0
    out[(tag & 0x0C) != 0] = 5.0
    return out


def step_units(config: SensorConfig) -> tuple[str, ...]:
    """The step units the configuration's pattern has (the Risley track has frames only)."""
    return tuple(name for name, unit in STEP_UNITS.items() if unit in config.unit_points)


def pattern_colours(config: SensorConfig) -> tuple[str, ...]:
    """The pattern colour modes that mean something for the configuration's pattern."""
    if config.pattern_model in SERIES_MODELS:
        return ("time", "laser")
    return tuple(name for name in PATTERN_COLOURS if name != "laser")


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
    caster : RayCaster, optional
        Built for ``scene``; default an :class:`~livox_viz.scene.raycast.EmbreeCaster`.
    trajectory : Trajectory, optional
        A moving vehicle; playback stops at its end.
    """

    def __init__(self, config: SensorConfig, scene: Scene, seed: int = 0, preset_name: str = "",
                 vehicle_pose: Pose | None = None, caster: RayCaster | None = None,
                 trajectory: Trajectory | None = None) -> None:
        self.trajectory = trajectory
        self.scene = scene
        self.seed = seed
        self.preset_name = preset_name
        self.vehicle_pose = vehicle_pose or scene.vehicle_pose
        self.caster = caster or EmbreeCaster(scene.mesh)
        self.playback = Playback()
        self.display = DisplayOptions()
        self._window: float | None = WINDOWS[FIRST_WINDOW]
        self.message = ""
        #: Points a refilled window (a new integration window, a seek) casts per tick; 0 casts it all at once
        #: (renders, tests). The window sets it: a million points at once held its UI thread for seconds.
        self.fill_per_tick = 0
        #: Whether the pattern's points are cast into the scene (the window plays the pattern alone until the
        #: caster's compiled loops are loaded, then :meth:`start_casting`).
        self.casting = True
        self._filling_to: float | None = None
        self._fill_from = 0
        #: Points of the model's stream skipped since the last restart because a tick fell too far behind
        #: (:data:`MAX_POINTS_PER_TICK`): fired by the sensor, never drawn.
        self.skipped_points = 0
        self.overlay = ReferenceOverlay()
        #: How the scenes the window cycles to are opened (``open_scene``'s ``up`` and ``reflectance``): as the
        #: one it started on.
        self.scene_options: dict[str, object] = {}
        #: A receiver with ``poll() -> list of LivoxFrame`` (the live view); None plays the model.
        self.source = None
        #: What the live view's stream did (set with :attr:`source`).
        self.live: LiveStats | None = None
        #: Where the scene, the trajectory and the reference came from, as the command line names them
        #: (``scene``, ``up``, ``reflectance``, ``pose``, ``trajectory``, ``trajectory_speed``, ``reference``...):
        #: what a screenshot's sidecar needs to make them again.
        self.sources: dict[str, object] = {}
        self._received_points = 0
        self._listeners: list[Callable[[str], None]] = []
        check_window(config, self._window)
        self.config = config
        #: The configuration as its preset gave it: what a parameter's reset goes back to.
        self.preset_config = config
        #: Every change of the configuration, to undo and redo (Edit menu, Ctrl+Z / Ctrl+Shift+Z).
        self.history = ConfigHistory()
        self._fit_display()
        self._make_rings()
        #: Which scan this is, counted up at each restart: what was picked in an earlier one is not in this one.
        self.scan_number = 0
        self.restart()

    # Listeners ----------------------------------------------------------------------------
    def subscribe(self, listener: Callable[[str], None]) -> None:
        """Call ``listener(what)`` after every change of ``"config"`` or ``"scene"``."""
        self._listeners.append(listener)

    def _changed(self, what: str) -> None:
        for listener in self._listeners:
            listener(what)

    # Configuration, scene, pose ------------------------------------------------------------
    @property
    def window(self) -> float | None:
        """The integration window, seconds, or None for unlimited."""
        return self._window

    @property
    def window_index(self) -> int | None:
        """The window's place among the presets :data:`WINDOWS`, or None for a typed value that is none of them."""
        return WINDOWS.index(self._window) if self._window in WINDOWS else None

    @property
    def state(self) -> ConfigState:
        """The configuration shown, with its preset: what an undo step keeps."""
        return ConfigState(self.config, self.preset_name, self.preset_config)

    def set_config(self, config: SensorConfig, preset_name: str | None = None, *, record: bool = True) -> None:
        """Show another configuration: restart the scan and tell every view. While paused, the new scan is shown
        filled to the time that was shown (still paused), not empty at t = 0.

        Parameters
        ----------
        config : SensorConfig
        preset_name : str, optional
            Shown as this preset (its values become what a parameter's reset goes back to).
        record : bool
            Whether the change is a step of :attr:`history` (False: an undo or redo applying one).

        Raises
        ------
        LivoxVizError
            If its integration window would hold more points than :data:`~livox_viz.workload.WINDOW_BUDGET`.
        """
        check_points(window_capacity(self.window, config.point_rate),
                     f"a {config.point_rate:,} pts/s pattern in the integration window", WINDOW_BUDGET)
        before = self.state
        resize = config.point_rate != self.config.point_rate or config.field_of_view != self.config.field_of_view
        self.config = config
        if preset_name is not None:
            self.preset_name = preset_name
            self.preset_config = config
        if record and self.state != before:
            self.history.record(before)
        if resize:
            self._make_rings()
        source = self.overlay.source
        if source is not None and source.plane != config.pattern_plane:
            # Another plane's angles would be drawn as if they were ours.
            self.overlay.set_source(None, 0.0)
            self.message = f"reference {source.name} removed: it is a {source.plane} pattern"
        self._fit_display()
        shown = self.shown_time
        self.restart()
        if self.playback.paused and self.source is None and shown > 0:
            # Tuning while paused: the new scan is shown as it stands at the time that was shown, still paused.
            # From t = 0 the view stayed empty until play (a first-use trial).
            self.played = shown
            self._refill(shown)
        self._changed("config")

    def _fit_display(self) -> None:
        """Keep the step unit and pattern colour to those the configuration's pattern has."""
        if self.display.step_unit not in step_units(self.config):
            self.display.step_unit = step_units(self.config)[-1]
        if self.display.pattern_colour not in pattern_colours(self.config):
            self.display.pattern_colour = "time"

    def set_param(self, name: str, value: float) -> bool:
        """Change one configuration field and restart; False (and a message) if the value is not allowed."""
        try:
            config = self.config.with_param(name, value)
            if config != self.config:
                self.set_config(config)
        except LivoxVizError as exc:
            self.message = str(exc)
            return False
        self.message = ""
        return True

    def undo(self) -> bool:
        """Give back the configuration before the last change; False (and a message) if there is none."""
        return self._step_history(self.history.undo_target(), self.history.undone, "undo")

    def redo(self) -> bool:
        """Make the last undone change again; False (and a message) if there is none."""
        return self._step_history(self.history.redo_target(), self.history.redone, "redo")

    def _step_history(self, target: ConfigState | None, take: Callable[[ConfigState], ConfigState],
                      word: str) -> bool:
        if target is None:
            self.message = f"nothing to {word}"
            return False
        current = self.state
        what = describe_change(target, current) if word == "undo" else describe_change(current, target)
        # Shown first: a window too full for the target's rate is refused there, the stacks left as they were.
        self.set_config(target.config, target.preset_name, record=False)
        self.preset_config = target.preset_config  # the preset's own values, not the tuned ones shown
        take(current)
        self.message = f"{word}: {what}"
        return True

    def set_returns_model(self, model: str) -> None:
        """Cast with the "ideal" or the "datasheet" return model (a configuration without one gets the Mid-70's)."""
        self.set_config(self.config.with_returns_model(model))

    def set_jitter_scope(self, scope: str) -> None:
        """Switch when the random rotation is added ("flower" or "figure") and restart."""
        self.set_config(replace(self.config, jitter_scope=scope))

    def set_scene(self, scene: Scene, caster: RayCaster | None = None) -> None:
        """Cast into another scene (from its own default vehicle pose) and restart the scan.

        ``caster``: one already built for ``scene`` (the window builds it on a worker: a large mesh's takes seconds).
        """
        self.caster = caster if caster is not None else EmbreeCaster(scene.mesh)
        self.scene = scene
        self.vehicle_pose = scene.vehicle_pose
        self.restart()
        self._changed("scene")

    @property
    def sensor_pose(self) -> Pose:
        """The sensor's pose in the world now, from the configuration's mount and the vehicle."""
        return self.mounted.sensor_pose_at(self._pose_time())

    @property
    def vehicle_pose_now(self) -> Pose:
        """The vehicle's pose at the current scan time (its fixed pose when it does not move)."""
        if self.trajectory is None:
            return self.vehicle_pose
        return self.trajectory.pose_at(self._pose_time())

    def _pose_time(self) -> float:
        if self.trajectory is None:
            return 0.0
        low, high = self.trajectory.span
        return min(max(self.scan_time, low), high)

    # Scan ----------------------------------------------------------------------------------
    def restart(self) -> None:
        """Start the pattern again from scan time 0."""
        self.pattern = make_pattern(self.config, seed=self.seed)
        self.mounted = MountedCaster(self.config, self.caster, self.vehicle_pose, self.trajectory, self.seed)
        self.scan_number += 1
        self.scan_time = 0.0
        #: The farthest scan time this scan has reached, seconds: what the time scrubber spans (a restart, by a
        #: preset, a parameter or x, begins another scan: the times before it are not this one's).
        self.played = 0.0
        self.playback.restart()
        self.frame_index = 0
        self.skipped_points = 0
        self._filling_to = None
        self._clear_rings()
        self.overlay.refill(0.0)

    def set_window(self, index: int) -> None:
        """Pick :data:`WINDOWS` ``[index]`` and refill it from the stream (keeps the scan time)."""
        if not 0 <= index < len(WINDOWS):
            raise LivoxVizError(f"window index {index}; allowed: 0 to {len(WINDOWS) - 1}")
        self.set_window_seconds(WINDOWS[index])

    def set_window_seconds(self, seconds: float | None) -> None:
        """Integrate over ``seconds`` (:data:`WINDOW_RANGE`; None = unlimited) and refill the window from the
        stream (keeps the scan time).

        Raises
        ------
        LivoxVizError
            For a value outside :data:`WINDOW_RANGE`, or a window the point budget cannot hold.
        """
        seconds = check_window_seconds(seconds)
        check_window(self.config, seconds)
        self._window = seconds
        self._make_rings()
        # The time the window was at, or being filled to (a window still filling has not reached it yet).
        self._refill(self._filling_to if self._filling_to is not None else self.scan_time)

    def start_casting(self) -> None:
        """Cast from now on, the window that ends now cast again first (the pattern played meanwhile)."""
        self.casting = True
        target = self._filling_to if self._filling_to is not None else self.scan_time
        self._clear_rings()
        self._refill(target)

    def seek(self, scan_time: float) -> None:
        """Show the integration window that ends at ``scan_time`` seconds (the time scrubber), cast afresh: the
        same points a scan played to that time holds. Playback pauses."""
        if not math.isfinite(scan_time) or scan_time < 0:
            raise LivoxVizError(f"scan time {scan_time!r}; allowed: a time >= 0 s")
        if self.trajectory is not None:
            scan_time = min(scan_time, self.trajectory.span[1])
        self.playback.paused = True
        self._clear_rings()
        self._refill(scan_time)

    def _refill(self, target: float) -> None:
        """Fill the window that ends at ``target`` seconds from the stream: exactly the points a scan played to
        ``target`` holds (the last ring's worth of the window's), cast in ticks' worth of points."""
        rate = self.config.point_rate
        start_time = 0.0 if self.window is None else max(0.0, target - self.window)
        last = points_before(target, rate)
        first = max(points_before(start_time, rate), last - self.pattern_ring.capacity)
        self.pattern = make_pattern(self.config, seed=self.seed)
        self.pattern.skip(first)
        self.pattern_ring.clear(first)
        self.scan_time = max(start_time, first / rate)
        self.overlay.refill(self.scan_time)
        if self.fill_per_tick:
            self._filling_to = target  # the ticks fill it, a share each (:meth:`tick`)
            self._fill_from = first
            self.advance_to(min(target, (first + self.fill_per_tick) / rate))
            return
        while self.pattern.position + MAX_POINTS_PER_TICK < last:
            self.advance_to((self.pattern.position + MAX_POINTS_PER_TICK) / rate)
        self.advance_to(target)

    @property
    def shown_time(self) -> float:
        """The scan time the window is at, seconds: the one it is being filled to while it fills (the points
        filled so far are older; the clock shown ran backwards and forwards while a window filled)."""
        return self._filling_to if self._filling_to is not None else self.scan_time

    @property
    def shown_frame(self) -> int:
        """The frame of :attr:`shown_time` (-1 before the first)."""
        if self._filling_to is None:
            return self.frame_index
        return self._frame_ending(points_before(self._filling_to, self.config.point_rate))

    def _frame_ending(self, points: int) -> int:
        """The frame the ``points``-th point of the stream falls in (-1 for none)."""
        return (points - 1) // self.config.points_per_frame

    @property
    def filling(self) -> float | None:
        """How far a window being filled over several ticks has come, 0 to 1; None when none is."""
        if self._filling_to is None:
            return None
        last = points_before(self._filling_to, self.config.point_rate)
        return (self.pattern.position - self._fill_from) / max(last - self._fill_from, 1)

    def _make_rings(self) -> None:
        capacity = window_capacity(self.window, self.config.point_rate)
        self.pattern_ring = PointRing(capacity)
        self.scene_ring = PointRing(capacity, sensor_frame=True)
        fov = self.config.field_of_view
        self.density = DensityGrid(fov.bounds)
        self.coverage_counts = CoverageCounts(fov)
        self.pattern_ring.on_evict = self._count_out

    def _clear_rings(self) -> None:
        for ring in (self.pattern_ring, self.scene_ring):
            ring.clear()
        self.density.clear()
        self.coverage_counts.clear()

    def _count_in(self, xyz: np.ndarray) -> None:
        kept = xyz[-self.pattern_ring.capacity :]
        self.density.add(kept)
        self.coverage_counts.add(kept)

    def _count_out(self, xyz: np.ndarray) -> None:
        self.density.remove(xyz)
        self.coverage_counts.remove(xyz)

    # Playback ------------------------------------------------------------------------------
    def tick(self, now: float | None = None) -> int:
        """Advance by the wall time since the last tick; returns the points added.

        With a live :attr:`source` the frames that arrived are shown instead of the model's pattern.
        """
        if self._filling_to is not None:  # a window still being filled: a share a tick, the clock held
            target = self._filling_to
            step = min(target, (self.pattern.position + self.fill_per_tick) / self.config.point_rate)
            added = self.advance_to(step)
            if step >= target:
                self._filling_to = None
            self.playback.restart()
            return added
        if self.source is not None:
            if self.playback.paused:
                self.set_aside_arrivals()
                return 0
            arrived = self.source.poll()
            if self.live is not None:
                self.live.heard(arrived, time.monotonic())
            received = [ReceivedFrame(f, self.config.range_max, self.config.data_check_freq,
                                      plane=self.config.pattern_plane)
                        for f in arrived]
            return sum(self.add_received(frame) for frame in received)
        return self.advance_to(self.scan_time + self.playback.elapsed(now))

    def set_aside_arrivals(self) -> int:
        """Paused live view: read the frames that arrived and set them aside, counted (play then resumes with the
        stream as it is now, not a burst of old frames, and the rates stay true while paused); how many."""
        if self.source is None:
            return 0
        arrived = self.source.poll()
        if self.live is not None:
            self.live.heard(arrived, time.monotonic(), drawn=False)
        return len(arrived)

    def live_line(self) -> str:
        """The live view's line (:meth:`LiveStats.line`), or "" when the window plays the model."""
        if self.live is None:
            return ""
        drops = getattr(getattr(self.source, "assembler", None), "drops", {})
        return self.live.line(time.monotonic(), self.config.data_check_freq,
                              drops.get("lost frames (frame ids skipped)", 0))

    def add_received(self, frame: ReceivedFrame) -> int:
        """Show a received frame: its angles (from the decoded points) in the pattern view, its points in the scene."""
        count = len(frame)
        index = np.arange(self._received_points, self._received_points + count)
        self._received_points += count
        self.scan_time = frame.timestamp + 1.0 / self.config.data_check_freq
        self.played = max(self.played, self.scan_time)
        self.frame_index = frame.index
        xyz = np.zeros((count, 3), dtype=np.float32)
        xyz[:, :2] = frame.xy_deg
        self.pattern_ring.write(xyz, self.pattern_scalars(index, frame.t), frame.t, index)
        self._count_in(xyz)
        self._add_cloud(frame, index)
        self._drop_old()
        return count

    def advance_to(self, scan_time: float) -> int:
        """Emit (and cast) every point before ``scan_time`` seconds; returns how many.

        With a trajectory, playback stops (and pauses) at its end: there is no pose after it.
        """
        if self.trajectory is not None and scan_time > self.trajectory.span[1]:
            scan_time = self.trajectory.span[1]
            if not self.playback.paused:
                self.playback.paused = True
                self.message = f"end of the trajectory {self.trajectory.name} at {scan_time:g} s (x restarts)"
        target = points_before(scan_time, self.config.point_rate)
        missing = target - self.pattern.position
        if missing > MAX_POINTS_PER_TICK:
            # Too far behind: jump, keeping only what the window can show.
            keep = min(self.pattern_ring.capacity, MAX_POINTS_PER_TICK)
            self.pattern.skip(missing - keep)
            self.skipped_points += missing - keep
            missing = keep
        if missing <= 0:
            self.scan_time = max(self.scan_time, scan_time)
            self.played = max(self.played, self.scan_time)
            return 0
        chunk = self.pattern.take(missing)
        self.scan_time = scan_time
        self.played = max(self.played, scan_time)
        if self.overlay.advance_to(scan_time):
            source = self.overlay.source
            self.message = (f"reference {source.name} ends at {source.end:.3g} s (a recording is not looped): its "
                            "last window is held")
        self._add_pattern(chunk)
        if self.casting:
            frame = self.mounted.cast(chunk)
            self._add_cloud(frame, frame.stream_index)
        self._drop_old()
        self.frame_index = self._frame_ending(target)
        return missing

    def step(self, unit: str | None = None) -> int:
        """Advance to the next boundary of ``unit`` (default the display's step unit); returns the points added."""
        unit = unit or self.display.step_unit
        if unit not in step_units(self.config):
            raise LivoxVizError(f"step unit {unit!r}; allowed: {', '.join(step_units(self.config))}")
        size = self.config.unit_points[STEP_UNITS[unit]]
        boundary = (self.pattern.position // size + 1) * size
        return self.advance_to(boundary / self.config.point_rate)

    def _add_pattern(self, chunk: PatternChunk) -> None:
        xyz = np.zeros((len(chunk), 3), dtype=np.float32)
        xyz[:, :2] = chunk.xy_deg
        self.pattern_ring.write(xyz, self.pattern_scalars(chunk.index, chunk.t), chunk.t, chunk.index)
        self._count_in(xyz)

    def _add_cloud(self, frame: PointFrame, index: np.ndarray) -> None:
        """The scene ring gets the decoded returns, placed in the world with each point's pose
        (or, in the sensor-frame mode, all with the pose at the end of the chunk)."""
        if len(frame) == 0:
            return
        if self.display.cloud_frame == "sensor":
            end = frame.end_pose
            world = end.origin + frame.xyz_decoded @ end.rotation.T
        else:
            world = frame.xyz_world_decoded
        self.scene_ring.write(world, self.scene_scalars(world, frame.range_m, frame.t, frame.reflectivity, frame.tag),
                              frame.t, index, frame.reflectivity, frame.tag, sensor_xyz=frame.xyz_decoded,
                              range_m=frame.range_m, return_number=frame.return_number)

    def _drop_old(self) -> None:
        if self.window is not None:
            limit = self.scan_time - self.window
            self.pattern_ring.drop_older_than(limit)
            self.scene_ring.drop_older_than(limit)

    # Colours -------------------------------------------------------------------------------
    def pattern_scalars(self, stream_index: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Scalars of pattern points for the current colour mode, ``(n,)`` float32."""
        mode = self.display.pattern_colour
        if mode == "time":
            return t.astype(np.float32)
        if mode == "laser":
            return (stream_index % self.config.lasers).astype(np.float32)
        unit, within = PATTERN_COLOURS[mode]
        sizes = self.config.unit_points
        return ((stream_index // sizes[unit]) % (sizes[within] // sizes[unit])).astype(np.float32)

    def pattern_scalar_range(self) -> tuple[float, float]:
        """Colour range of the pattern view for the current mode."""
        mode = self.display.pattern_colour
        if mode == "time":
            return self._time_range(self.pattern_ring)
        if mode == "laser":
            top = self.config.lasers
        else:
            unit, within = PATTERN_COLOURS[mode]
            top = self.config.unit_points[within] // self.config.unit_points[unit]
        return 0.0, float(max(top - 1, 1))

    def scene_scalars(self, world: np.ndarray, ranges: np.ndarray, t: np.ndarray,
                      reflectivity: np.ndarray | None = None, tag: np.ndarray | None = None) -> np.ndarray:
        """Scalars of scene points for the current colour mode, ``(n,)`` float32.

        ``reflectivity`` shows the byte (0-255); ``return/tag`` the index of :data:`TAG_CLASSES`: return 0-3 of
        a clean point, 4 a mixed point (spatial-noise bits), 5 noise (intensity-noise bits: a false alarm).
        """
        mode = self.display.scene_colour
        if mode == "range":
            return ranges.astype(np.float32)
        if mode == "height":
            return (-world[:, 2]).astype(np.float32)
        if mode == "reflectivity":
            return (np.zeros(len(world)) if reflectivity is None else reflectivity).astype(np.float32)
        if mode == "return/tag":
            return tag_classes(np.full(len(world), 0x10, np.uint8) if tag is None else tag)
        return t.astype(np.float32)

    def scene_scalar_range(self, automatic: bool = False) -> tuple[float, float]:
        """Colour range of the scene view for the current mode: the one the user fixed, else (or with
        ``automatic``) the data's."""
        mode = self.display.scene_colour
        fixed = None if automatic else self.display.scene_colour_ranges.get(mode)
        if fixed is not None:
            return fixed
        if mode == "range":
            return 0.0, min(self.config.range_max, 150.0)
        if mode == "height":
            return 0.0, 30.0
        if mode == "reflectivity":
            return 1.0, 255.0
        if mode == "return/tag":
            return -0.5, len(TAG_CLASSES) - 0.5
        return self._time_range(self.scene_ring)

    def _time_range(self, ring: PointRing) -> tuple[float, float]:
        """The time colours' range: the integration window up to now, or the times ``ring`` holds of the unlimited
        one (its last million points: a bar from 0 s made 2 minutes' scan one flat red); before any point, the
        window's length from 0 (a bar from 0 to 1e-06 s said nothing)."""
        if self.scan_time <= 0.0:
            return 0.0, self.window if self.window is not None else 1.0
        if self.window is not None:
            low = self.scan_time - self.window
        else:
            low = float(ring.times[ring.tail]) if ring.count else 0.0
        return max(0.0, min(low, self.scan_time)), self.scan_time

    def recolour(self) -> None:
        """Recompute all scalars after a colour mode change.

        Slice by slice of the rings (no gather of a million slots), and the scene's ranges in float32 from the
        stored float32 points: a colour key costs tens of milliseconds, not hundreds.
        """
        ring = self.pattern_ring
        for piece in ring.live_pieces():
            ring.scalars[piece] = self.pattern_scalars(ring.stream_index[piece], ring.times[piece])
        ring = self.scene_ring
        origin = self.sensor_pose.origin.astype(np.float32)
        for piece in ring.live_pieces():
            world = ring.positions[piece]
            ranges = np.square(world[:, 0] - origin[0])
            for axis in (1, 2):
                ranges += np.square(world[:, axis] - origin[axis])
            np.sqrt(ranges, out=ranges)
            ring.scalars[piece] = self.scene_scalars(world, ranges, ring.times[piece], ring.reflectivity[piece],
                                                     ring.tag[piece])

    # What is drawn, and what a click finds -------------------------------------------------
    def points_fired_in_window(self) -> int:
        """Points the sensor fired in the integration window that ends now (since the start, when unlimited).

        What the window would hold if nothing were skipped or capped; a live source counts what arrived.
        """
        if self.source is not None:
            return self.pattern_ring.count
        rate = self.config.point_rate
        start = 0.0 if self.window is None else max(0.0, self.scan_time - self.window)
        return points_before(self.scan_time, rate) - points_before(start, rate)

    def nearest_pattern_point(self, x_deg: float, y_deg: float, y_scale: float = 1.0) -> dict[str, float] | None:
        """The live pattern sample nearest to ``(x_deg, y_deg)`` in the pattern's plane, or None when empty.

        ``y_scale``: how much longer a degree of y is drawn than a degree of x (the panorama's stretch), so that
        the nearest is the nearest as drawn.

        Returns
        -------
        dict
            ``x_deg``, ``y_deg`` (the sample's angles), ``t_s`` (its time, seconds), ``index`` (its number in
            the stream), ``distance_deg`` (from the point asked).
        """
        ring = self.pattern_ring
        if ring.count == 0:
            return None
        best: tuple[float, int] | None = None
        for piece in ring.live_pieces():
            xy = ring.positions[piece, :2].astype(np.float64)
            d2 = np.square(xy[:, 0] - x_deg) + np.square((xy[:, 1] - y_deg) * y_scale)
            k = int(np.argmin(d2))
            if best is None or d2[k] < best[0]:
                best = (float(d2[k]), piece.start + k)
        assert best is not None
        slot = best[1]
        x, y = float(ring.positions[slot, 0]), float(ring.positions[slot, 1])
        return {"x_deg": x, "y_deg": y, "t_s": float(ring.times[slot]), "index": int(ring.stream_index[slot]),
                "distance_deg": math.hypot(x - x_deg, y - y_deg)}

    def scene_point(self, slot: int) -> dict[str, float | int]:
        """What the scene's cloud holds for the point in ``slot`` of its ring (a click on it).

        Returns
        -------
        dict
            ``xyz_world`` (NED, metres), ``xyz_sensor`` (decoded, sensor FRD, metres), ``range_m``,
            ``azimuth_deg`` (positive to the sensor's right), ``elevation_deg`` (positive up),
            ``reflectivity`` (byte), ``tag`` (byte), ``return_number`` (1-3; 0 unknown), ``t_s``, ``frame``.
        """
        ring = self.scene_ring
        if not 0 <= slot < ring.capacity:
            raise LivoxVizError(f"slot {slot}; allowed: 0 to {ring.capacity - 1}")
        local = ring.sensor_xyz[slot].astype(np.float64)
        t = float(ring.times[slot])
        if self.source is None:
            frame = int(ring.stream_index[slot]) // self.config.points_per_frame
        else:
            frame = math.floor(t * self.config.data_check_freq + 1e-9)
        return {
            "xyz_world": ring.positions[slot].astype(np.float64).tolist(), "xyz_sensor": local.tolist(),
            "range_m": float(ring.range_m[slot]),
            "azimuth_deg": math.degrees(math.atan2(local[1], local[0])),
            "elevation_deg": math.degrees(math.atan2(-local[2], math.hypot(local[0], local[1]))),
            "reflectivity": int(ring.reflectivity[slot]), "tag": int(ring.tag[slot]),
            "return_number": int(ring.return_number[slot]), "t_s": t, "frame": frame,
        }

    # Measures ------------------------------------------------------------------------------
    def visible_coverage(self) -> float:
        """FOV coverage of the points the pattern view shows (5 mrad cells), kept up to date per point."""
        return self.coverage_counts.coverage()
