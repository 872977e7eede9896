"""The livox-viz window: two linked views, parameter sliders, playback, heads-up text, files.

One controller object owns the plotter: every slider calls :meth:`LivoxVizApp.on_param`
(name, value), which asks the :class:`~widgets.session.Session` for the new
configuration and redraws; keys and the timer go through the same session.
"""

from __future__ import annotations

import json
import math
import os
import time
from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np
import pyvista as pv

from livox_viz import LivoxVizError, SensorConfig, list_presets, load_config
from livox_viz.atomic import atomic_path, write_text_atomic
from livox_viz.config import PARAM_RANGES, save_config
from livox_viz.presets import user_preset_dir

from .session import PATTERN_COLOURS, SCENE_COLOURS, SPEED_RANGE, STEP_UNITS, WINDOWS, Session, window_label
from .views import PatternView, SceneView

SCREENSHOT_DIR = Path("screenshots")
TIMER_MS = 33
#: The sliders under the pattern view and under the scene view: (parameter, short title).
PATTERN_SLIDERS: tuple[tuple[str, str], ...] = (
    ("camera_fov", "FOV, deg"),
    ("petal_height", "[1] petal h, deg"),
    ("spacing_exponent", "[2] spacing p"),
    ("tip_exponent", "[3] tip q"),
    ("figure8_per_flower", "[4] figure-8s/flower"),
    ("flowers_per_figure", "[5] flowers/figure"),
    ("jitter_max_deg", "[6] jitter, deg"),
    ("range_max", "[0] range, m"),
)
SENSOR_SLIDERS: tuple[tuple[str, str], ...] = (
    ("data_width", "DataWidth W"),
    ("data_height", "DataHeight H"),
    ("data_check_freq", "DataCheckFreq F, Hz"),
)
HELP_TEXT = """livox-viz keys
space      pause / play
Right      step one {unit}
u          step unit: arc petal figure-8 flower frame
x          reset the scan to t = 0
Up / Down  speed x2 / /2 (now {speed:g}x)
i          integration window (now {window})
c          pattern colours: time figure-8 petal
           flower arc
k          scene colours: range height time
j          jitter per flower / figure (now {scope})
s          screenshot + JSON sidecar
p          save the sliders as a user preset
n / b      next / previous preset
r          reset the cameras
o / l      reference overlay on/off / its window
g          drawing: auto / points / density image
m          next scene (built-in, then your mesh files)
h          this help     q  quit"""


def slider_range(name: str) -> tuple[float, float]:
    """The slider's ends: the validated range, open ends nudged inside."""
    spec = PARAM_RANGES[name]
    nudge = 1 if spec.integer else max((spec.high - spec.low) * 1e-3, 1e-3)
    low = spec.low + nudge if spec.low_open else spec.low
    high = spec.high - nudge if spec.high_open else spec.high
    return float(low), float(high)


class LivoxVizApp:
    """The GUI controller.

    Parameters
    ----------
    session : Session
    off_screen : bool
        Render without a window (tests, ``livox-viz render``).
    window_size : tuple of int
        Pixels.
    views : {"both", "pattern", "scene"}
        ``both`` is the full GUI with sliders; one view alone is for renders.
    screenshot_dir : Path
        Where ``s`` saves.
    """

    def __init__(self, session: Session, off_screen: bool = False, window_size: tuple[int, int] = (1600, 900),
                 views: str = "both", screenshot_dir: Path = SCREENSHOT_DIR) -> None:
        if views not in ("both", "pattern", "scene"):
            raise LivoxVizError(f"view {views!r}; allowed: both, pattern, scene")
        self.session = session
        self.views = views
        self.screenshot_dir = Path(screenshot_dir)
        self.window_size = window_size
        if views == "both":
            plotter = pv.Plotter(off_screen=off_screen, shape=(2, 2), row_weights=[5, 1], window_size=window_size,
                                 border=False, title="livox-viz")
        else:
            plotter = pv.Plotter(off_screen=off_screen, window_size=window_size, title="livox-viz")
        # Multisampling costs a factor of 3 on a million points in software GL; smooth lines instead.
        plotter.ren_win.SetMultiSamples(0)
        plotter.ren_win.LineSmoothingOn()
        self.plotter = plotter
        self.pattern_view = PatternView(plotter, session, (0, 0)) if views in ("both", "pattern") else None
        scene_spot = (0, 1) if views == "both" else (0, 0)
        self.scene_view = SceneView(plotter, session, scene_spot) if views in ("both", "scene") else None
        self.sliders: dict[str, Any] = {}
        self._fps = 0.0
        self._last_render = None
        self._coverage_at = -1.0
        self._reference_coverage: float | None = None
        self._help_visible = False
        self._preset_cursor = -1
        self._scene_cursor = -1
        self._config_shown = session.config
        self._ready = False  # pyvista calls each slider's callback once as it is created
        if views == "both":
            self._add_sliders()
        self._add_text()
        self._add_keys()
        self._ready = True
        self.refresh()

    # Construction ---------------------------------------------------------------------
    def _add_sliders(self) -> None:
        plotter = self.plotter
        style = dict(title_height=0.1, title_color="#dde3ea", color="#dde3ea", slider_width=0.04, tube_width=0.008)
        plotter.subplot(1, 0)
        plotter.set_background("#0c0f15")
        for k, (name, title) in enumerate(PATTERN_SLIDERS):
            row, col = divmod(k, 4)
            x0 = 0.03 + col * 0.245
            y = 0.68 - row * 0.45
            self._param_slider(name, title, (x0, y), (x0 + 0.2, y), style)
        plotter.subplot(1, 1)
        plotter.set_background("#0c0f15")
        for k, (name, title) in enumerate(SENSOR_SLIDERS):
            x0 = 0.03 + k * 0.245
            self._param_slider(name, title, (x0, 0.68), (x0 + 0.2, 0.68), style)
        self.sliders["speed"] = plotter.add_slider_widget(
            self.on_speed_slider, rng=[math.log10(SPEED_RANGE[0]), math.log10(SPEED_RANGE[1])],
            value=math.log10(self.session.playback.speed), title="speed, log10 x", pointa=(0.03, 0.23),
            pointb=(0.23, 0.23), interaction_event="always", fmt="%.2f", **style,
        )
        self.sliders["window"] = plotter.add_slider_widget(
            self.on_window_slider, rng=[0, len(WINDOWS) - 1], value=self.session.window_index,
            title="window .1 .5 1 2 s inf", pointa=(0.275, 0.23), pointb=(0.475, 0.23),
            interaction_event="end", fmt="%.0f", **style,
        )
        for widget in self.sliders.values():
            widget.GetRepresentation().SetLabelHeight(0.09)

    def _param_slider(self, name: str, title: str, a: tuple[float, float], b: tuple[float, float],
                      style: dict[str, Any]) -> None:
        spec = PARAM_RANGES[name]
        widget = self.plotter.add_slider_widget(
            lambda value, _name=name: self.on_param(_name, value),
            rng=list(slider_range(name)), value=self.session.config.param_value(name), title=title,
            pointa=a, pointb=b, interaction_event="end", fmt="%.0f" if spec.integer else "%.4g", **style,
        )
        self.sliders[name] = widget

    def _add_text(self) -> None:
        plotter = self.plotter
        plotter.subplot(0, 0)
        self.hud = plotter.add_text("", position="upper_left", font_size=10, color="#dde3ea", name="hud")
        self.keys_line = plotter.add_text("", position="lower_left", font_size=9, color="#8a96a8", name="keys")
        self.help_overlay = plotter.add_text("", position=(0.03, 0.25), viewport=True, font_size=9,
                                             color="#ffffff", name="help")
        help_style = self.help_overlay.GetTextProperty()
        help_style.SetFontFamilyToCourier()
        help_style.SetBackgroundColor(0.05, 0.06, 0.09)
        help_style.SetBackgroundOpacity(0.92)
        help_style.SetFrame(True)
        help_style.SetFrameColor(0.95, 0.76, 0.31)
        self.help_overlay.SetVisibility(False)
        self.scene_hud = None
        if self.scene_view is not None and self.pattern_view is not None:
            plotter.subplot(*self.scene_view.subplot)
            self.scene_hud = plotter.add_text("", position="upper_left", font_size=10, color="#dde3ea",
                                              name="scene-hud")
        self.message_text = plotter.add_text("", position="lower_left" if self.scene_hud else "lower_right",
                                             font_size=10, color="#ff7b72", name="message")
        self._message_corner = 0 if self.scene_hud else 1

    def _add_keys(self) -> None:
        bindings = {
            "space": self.toggle_pause, "Right": self.step, "u": self.cycle_step_unit, "x": self.reset,
            "Up": lambda: self.change_speed(2.0), "Down": lambda: self.change_speed(0.5),
            "i": self.cycle_window, "c": self.cycle_pattern_colour, "k": self.cycle_scene_colour,
            "j": self.toggle_jitter_scope, "s": self.save_screenshot, "p": self.save_preset,
            "n": lambda: self.cycle_preset(1), "b": lambda: self.cycle_preset(-1), "h": self.toggle_help,
            "r": self.reset_cameras, "o": self.toggle_reference, "l": self.cycle_reference_window,
            "g": self.cycle_drawing, "m": self.cycle_scene,
        }
        for key, action in bindings.items():
            self.plotter.add_key_event(key, self._guarded(action))

    def _guarded(self, action):
        """Run a key action; bad input becomes a message in the window, never a crash."""

        def run() -> None:
            try:
                action()
            except (LivoxVizError, OSError) as exc:
                self.session.message = str(exc)
            self.refresh()

        return run

    # Parameter changes ------------------------------------------------------------------
    def on_param(self, name: str, value: float) -> None:
        """A slider moved: snap integers, validate, restart the pattern from the new configuration."""
        spec = PARAM_RANGES[name]
        if spec.integer and math.isfinite(value):
            value = float(round(value))
        if not self.session.set_param(name, value):
            self._set_slider(name, self.session.config.param_value(name))
        else:
            self._set_slider(name, value)
        self.refresh()

    def _set_slider(self, name: str, value: float) -> None:
        widget = self.sliders.get(name)
        if widget is not None:
            widget.GetRepresentation().SetValue(value)

    def on_speed_slider(self, value: float) -> None:
        """The speed slider, in log10 of the speed."""
        self.session.playback.set_speed(10.0 ** value)
        self.refresh()

    def on_window_slider(self, value: float) -> None:
        """The integration window slider, an index into :data:`~widgets.session.WINDOWS`."""
        index = round(min(max(value, 0), len(WINDOWS) - 1))
        self._set_slider("window", index)
        if index != self.session.window_index:
            self.session.set_window(index)
        self.refresh()

    def _sync_sliders(self) -> None:
        for name, widget in self.sliders.items():
            if name in PARAM_RANGES:
                widget.GetRepresentation().SetValue(self.session.config.param_value(name))

    # Playback ---------------------------------------------------------------------------
    def toggle_pause(self) -> None:
        self.session.playback.paused = not self.session.playback.paused

    def step(self) -> None:
        """Pause and advance by one step unit."""
        self.session.playback.paused = True
        self.session.step()

    def cycle_step_unit(self) -> None:
        units = STEP_UNITS
        self.session.step_unit = units[(units.index(self.session.step_unit) + 1) % len(units)]

    def reset(self) -> None:
        self.session.restart()

    def change_speed(self, factor: float) -> None:
        speed = self.session.playback.set_speed(self.session.playback.speed * factor)
        self._set_slider("speed", math.log10(speed))

    def cycle_window(self) -> None:
        index = (self.session.window_index + 1) % len(WINDOWS)
        self.session.set_window(index)
        self._set_slider("window", index)

    def cycle_pattern_colour(self) -> None:
        modes = PATTERN_COLOURS
        self.session.pattern_colour = modes[(modes.index(self.session.pattern_colour) + 1) % len(modes)]
        self.session.recolour()

    def cycle_scene_colour(self) -> None:
        modes = SCENE_COLOURS
        self.session.scene_colour = modes[(modes.index(self.session.scene_colour) + 1) % len(modes)]
        self.session.recolour()

    def toggle_jitter_scope(self) -> None:
        self.session.set_jitter_scope("figure" if self.session.config.jitter_scope == "flower" else "flower")

    def cycle_scene(self) -> None:
        """The next scene: the shipped ones, then mesh files in the user's scenes folder.

        A file that does not load leaves the current scene and says why; the next press moves on.
        """
        from livox_viz.scene import open_scene, scene_choices

        choices = scene_choices()
        if self._scene_cursor < 0:
            names = [Path(c).name if os.sep in c else c for c in choices]
            self._scene_cursor = names.index(self.session.scene.name) if self.session.scene.name in names else -1
        self._scene_cursor = (self._scene_cursor + 1) % len(choices)
        scene = open_scene(choices[self._scene_cursor])
        self.session.set_scene(scene)
        self.session.message = f"scene {scene.name}"

    def cycle_drawing(self) -> None:
        """Pattern view: density image when points outnumber pixels (auto), always points, always density."""
        modes = ("auto", "points", "density")
        self.session.pattern_drawing = modes[(modes.index(self.session.pattern_drawing) + 1) % len(modes)]

    def toggle_reference(self) -> None:
        """Show or hide the measured pattern's overlay."""
        if self.session.reference is None:
            raise LivoxVizError("no reference pattern: start with --reference FILE (.npy or Livox CSV)")
        self.session.reference_visible = not self.session.reference_visible

    def cycle_reference_window(self) -> None:
        """The overlay's own integration window."""
        if self.session.reference is None:
            raise LivoxVizError("no reference pattern: start with --reference FILE (.npy or Livox CSV)")
        self.session.set_reference_window((self.session.reference_window_index + 1) % len(WINDOWS))

    def toggle_help(self) -> None:
        self._help_visible = not self._help_visible

    def reset_cameras(self) -> None:
        if self.pattern_view is not None:
            self.pattern_view.reset_camera()
        if self.scene_view is not None:
            self.scene_view.reset_camera()

    def tick(self, now: float | None = None) -> None:
        """One timer tick: advance the scan by the wall time passed, redraw."""
        self.session.tick(now)
        self.refresh()

    # Drawing ----------------------------------------------------------------------------
    def refresh(self) -> None:
        """Bring every actor and text up to date with the session (no render)."""
        if not self._ready:
            return
        session = self.session
        if session.config is not self._config_shown:
            if session.config.camera_fov != self._config_shown.camera_fov:
                if self.pattern_view is not None:
                    self.pattern_view.draw_guides()
                    self.pattern_view.reset_camera()
            if self.scene_view is not None and (session.config.camera_fov != self._config_shown.camera_fov
                                                or session.config.sensor_ang_euler
                                                != self._config_shown.sensor_ang_euler):
                self.scene_view.draw_vehicle()
            self._config_shown = session.config
            self._sync_sliders()
        if self.pattern_view is not None:
            self.pattern_view.update()
        if self.scene_view is not None:
            self.scene_view.update()
        self._update_text()

    def _update_text(self) -> None:
        session = self.session
        cfg = session.config
        now = time.monotonic()
        coverage_now = session.visible_coverage()  # kept per point by the session: cheap
        # The reference's coverage is counted afresh, so only twice a second (or when paused).
        refresh_reference = now - self._coverage_at > 0.5 or session.playback.paused
        if refresh_reference:
            self._coverage_at = now
        state = "paused" if session.playback.paused else f"{session.playback.speed:g}x"
        reference = ""
        if session.reference is not None:
            if refresh_reference or self._reference_coverage is None:
                self._reference_coverage = session.reference_coverage()
            shown = "" if session.reference_visible else " (hidden, o)"
            value = self._reference_coverage
            reference = (f"reference {session.reference.name}{shown}, window "
                         f"{window_label(session.reference_window)} (l): coverage "
                         f"{'-' if value is None else f'{100 * value:.1f} %'}\n")
        hud = (
            f"{session.preset_name or 'custom'}   {cfg.point_rate:,} pts/s   FOV {cfg.camera_fov:g} deg\n"
            f"t = {session.scan_time:8.3f} s   frame {max(session.frame_index, 0)}   {state}\n"
            f"window {window_label(session.window)}: {session.pattern_ring.count:,} pts, "
            f"coverage {100 * coverage_now:.1f} %\n"
            f"{reference}"
            f"colour: {session.pattern_colour}   drawing: {session.pattern_drawing} (g)   "
            f"step: {session.step_unit}   jitter per {cfg.jitter_scope}   "
            + (f"{self._fps:4.1f} fps" if self._fps else "")
        )
        scene_lines = ""
        if self.scene_view is not None:
            scene_lines = (f"scene {session.scene.name}: {len(session.scene.mesh.faces):,} triangles\n"
                           f"decoded cloud: {session.scene_ring.count:,} returns in the window\n"
                           f"colour: {session.scene_colour}  (k)")
        if self.scene_hud is not None:
            self.scene_hud.SetText(2, scene_lines)
        elif scene_lines:
            hud += "\n" + scene_lines
        self.hud.SetText(2, hud)
        self.keys_line.SetText(0, "space play/pause  Right step  Up/Down speed  i window  c/k colours  "
                                  "s screenshot  p preset  n/b presets  h help  q quit")
        self.help_overlay.SetInput(HELP_TEXT.format(unit=session.step_unit, speed=session.playback.speed,
                                                    window=window_label(session.window), scope=cfg.jitter_scope))
        self.help_overlay.SetVisibility(self._help_visible)
        self.message_text.SetText(self._message_corner, session.message)
        if "speed" in self.sliders:
            self.sliders["speed"].GetRepresentation().SetTitleText(f"speed {session.playback.speed:.3g}x")
            self.sliders["window"].GetRepresentation().SetTitleText(f"window {window_label(session.window)}")

    def render(self) -> None:
        """Render once and update the frames-per-second figure."""
        self.plotter.ren_win.Render()
        now = time.perf_counter()
        if self._last_render is not None:
            instant = 1.0 / max(now - self._last_render, 1e-6)
            self._fps = instant if self._fps == 0 else 0.8 * self._fps + 0.2 * instant
        self._last_render = now

    # Files ------------------------------------------------------------------------------
    def save_screenshot(self, folder: Path | None = None) -> Path:
        """Save the window as PNG with a JSON sidecar (configuration, seed, scan time, cameras)."""
        from PIL import Image

        folder = Path(folder) if folder is not None else self.screenshot_dir
        folder.mkdir(parents=True, exist_ok=True)
        stamp = datetime.now().strftime("%Y%m%d-%H%M%S-%f")[:-3]
        path = folder / f"livox-viz-{stamp}.png"
        suffix = 1
        while path.exists():
            path = folder / f"livox-viz-{stamp}-{suffix}.png"
            suffix += 1
        self.render()
        image = self.plotter.screenshot(None, return_img=True)
        with atomic_path(path) as tmp:
            Image.fromarray(np.asarray(image)).save(tmp, format="PNG")
        write_text_atomic(path.with_suffix(".json"), json.dumps(self.sidecar(), indent=2) + "\n")
        self.session.message = f"saved {path}"
        return path

    def sidecar(self) -> dict[str, Any]:
        """What a screenshot's JSON sidecar holds."""
        session = self.session
        cameras = {}
        for name, view in (("pattern", self.pattern_view), ("scene", self.scene_view)):
            if view is not None:
                camera = view.renderer.camera
                cameras[name] = {"position": list(camera.position), "focal_point": list(camera.focal_point),
                                 "up": list(camera.up), "parallel_scale": camera.parallel_scale,
                                 "view_angle": camera.view_angle}
        return {
            "preset": session.preset_name, "config": session.config.to_json_dict(), "seed": session.seed,
            "scan_time_s": session.scan_time, "window_s": session.window, "scene": session.scene.name,
            "vehicle_pose": session.vehicle_pose.as_array().tolist(), "pattern_colour": session.pattern_colour,
            "scene_colour": session.scene_colour, "cameras": cameras,
            "window_size": list(self.plotter.window_size),
        }

    def save_preset(self) -> Path:
        """Write the current configuration as a user preset (never over a shipped one)."""
        folder = user_preset_dir()
        folder.mkdir(parents=True, exist_ok=True)
        base = (self.session.preset_name or "custom").split("-tuned-")[0]
        path = folder / f"{base}-tuned-{datetime.now().strftime('%Y%m%d-%H%M%S')}.json"
        save_config(self.session.config, path)
        self.session.message = f"saved preset {path.stem}"
        return path

    def cycle_preset(self, direction: int) -> None:
        """Load the next (or previous) preset; an invalid one leaves the current configuration."""
        presets = list_presets()
        if not presets:
            return
        names = [p.name for p in presets]
        if self._preset_cursor < 0 and self.session.preset_name in names:
            self._preset_cursor = names.index(self.session.preset_name)
        self._preset_cursor = (self._preset_cursor + direction) % len(presets)
        info = presets[self._preset_cursor]
        config = load_config(info.path)
        self.load_config(config, info.name)

    def load_config(self, config: SensorConfig, name: str) -> None:
        """Show another configuration."""
        self.session.preset_name = name
        self.session.restart(config)
        self.session.message = f"preset {name}"

    # Running ----------------------------------------------------------------------------
    def show(self) -> None:
        """Open the window and play until it is closed."""
        iren = self.plotter.iren
        iren.add_observer("TimerEvent", lambda *_: self._on_timer())
        iren.create_timer(TIMER_MS, repeating=True)
        self.plotter.show(auto_close=True)

    def _on_timer(self) -> None:
        try:
            self.tick()
        except LivoxVizError as exc:
            self.session.message = str(exc)
        self.render()

    def close(self) -> None:
        self.plotter.close()


def render_offscreen(session: Session, seconds: float, path: Path, views: str = "both",
                     size: tuple[int, int] = (1600, 900)) -> Path:
    """Render what the GUI shows after ``seconds`` of scan time into a PNG (atomic)."""
    from PIL import Image

    app = LivoxVizApp(session, off_screen=True, window_size=size, views=views)
    try:
        session.playback.paused = True
        session.advance_to(seconds)
        app.refresh()
        app.render()
        image = app.plotter.screenshot(None, return_img=True)
        with atomic_path(path) as tmp:
            Image.fromarray(np.asarray(image)).save(tmp, format="PNG")
    finally:
        app.close()
    return path


def has_display() -> bool:
    """Whether a window can be opened (X11 or Wayland)."""
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
