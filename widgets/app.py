"""The livox-viz window: it wires the session to the views, the sliders, the heads-up text and the keys.

The controller is thin: every slider calls :meth:`LivoxVizApp.on_param`
(name, value), which asks the :class:`~livox_viz.widgets.session.Session` for the
new configuration; the session tells the views (they subscribe) and the
controller only brings the sliders back in line. Keys come from the one key
table in :mod:`livox_viz.widgets.keys`.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import math
import os
import sys
import threading
import time
from collections.abc import Callable, Mapping
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any

import pyvista as pv

from livox_viz import LivoxVizError, list_presets, load_config
from livox_viz.config.sensor import PARAM_RANGES
from livox_viz.core.blas import blas_threads

from . import files
from .charts import CurveCharts
from .controls import SLIDER_PAGES, Sliders
from .hud import HeadsUp
from .keys import KEYS
from .overlay import WINDOWS, PresetSource, TableSource
from .playback import next_choice
from .session import CLOUD_FRAMES, DRAWINGS, SCENE_COLOURS, Session, pattern_colours, step_units
from .views import PatternView, SceneView

TIMER_MS = 33


def quiet_vtk() -> None:
    """Silence VTK's own logging (its off-screen renders warn about the missing X server on every start)."""
    from vtkmodules.vtkCommonCore import vtkLogger, vtkObject

    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_OFF)
    vtkObject.GlobalWarningDisplayOff()


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
                 views: str = "both", screenshot_dir: Path = files.SCREENSHOT_DIR) -> None:
        if views not in ("both", "pattern", "scene"):
            raise LivoxVizError(f"view {views!r}; allowed: both, pattern, scene")
        if off_screen:
            quiet_vtk()
        self.session = session
        self.views = views
        self.screenshot_dir = Path(screenshot_dir)
        if views == "both":
            # Pattern, scene and the charts above; the sliders of each below.
            plotter = pv.Plotter(off_screen=off_screen, shape=(2, 3), row_weights=[5, 1], col_weights=[5, 4, 3],
                                 window_size=window_size, border=False, title="livox-viz")
        else:
            plotter = pv.Plotter(off_screen=off_screen, window_size=window_size, title="livox-viz")
        # Multisampling costs a factor of 3 on a million points in software GL; smooth lines instead.
        plotter.ren_win.SetMultiSamples(0)
        plotter.ren_win.LineSmoothingOn()
        self.plotter = plotter
        self.pattern_view = PatternView(plotter, session, (0, 0)) if views in ("both", "pattern") else None
        scene_spot = (0, 1) if views == "both" else (0, 0)
        self.scene_view = SceneView(plotter, session, scene_spot) if views in ("both", "scene") else None
        self.sliders: Sliders | None = None
        self.charts = CurveCharts(plotter, (0, 2), session) if views == "both" else None
        self._ready = False  # pyvista calls each slider's callback once as it is created
        if views == "both":
            self.sliders = Sliders(plotter, session.config, self.on_param, self.on_speed, self.on_window,
                                   session.playback.speed, session.window_index)
        self.hud = HeadsUp(plotter, self.pattern_view and self.pattern_view.subplot,
                           self.scene_view and self.scene_view.subplot)
        for row in KEYS:
            for key, method in row.bindings:
                plotter.add_key_event(key, self._guarded(getattr(self, method)))
        if plotter.iren is not None:
            # VTK's own character keys (e exits, f flies the camera, s/w switch surfaces, p picks) would act
            # too: our keys take the character away first.
            plotter.iren.interactor.AddObserver("CharEvent", _swallow_our_keys, 10.0)
        session.subscribe(self._on_change)
        self._last_render: float | None = None
        self._writer: ThreadPoolExecutor | None = None  # screenshots being written
        self._fit: tuple[Future, str, float] | None = None  # the f key's fit running: its future, reference, start
        self._reference_choices: tuple[tuple, list[str]] | None = None
        # Find numpy's BLAS now (80 ms among the VTK libraries), not in the first key that makes a Risley track.
        blas_threads()
        self._preset_cursor = -1
        self._scene_cursor = -1
        self._ready = True
        self._sync_sliders()
        self.refresh()

    def _guarded(self, action):
        """Run a key action; bad input becomes a message in the window, never a crash."""

        def run() -> None:
            try:
                action()
            except (LivoxVizError, OSError) as exc:
                self.session.message = str(exc)
            self.refresh()

        return run

    def _on_change(self, what: str) -> None:
        if what == "config":
            self._sync_sliders()

    def _sync_sliders(self) -> None:
        if self.sliders is not None:
            self.sliders.sync(self.session.config, self.session.playback.speed, self.session.window_index)

    # Sliders ----------------------------------------------------------------------------
    def on_param(self, name: str, value: float) -> None:
        """A slider moved: snap integers, validate, restart the pattern from the new configuration."""
        if not self._ready:
            return
        if PARAM_RANGES[name].integer and math.isfinite(value):
            value = float(round(value))
        self.session.set_param(name, value)
        self._sync_sliders()  # back to the value taken: snapped, or the old one if refused
        self.refresh()

    def on_speed(self, speed: float) -> None:
        """The speed slider, in x real time."""
        if not self._ready:
            return
        self.session.playback.set_speed(speed)
        self.sliders.show_playback(self.session.playback.speed, self.session.window_index)
        self.refresh()

    def on_window(self, index: int) -> None:
        """The integration window slider, an index into :data:`~livox_viz.widgets.overlay.WINDOWS`."""
        if not self._ready:
            return
        if index != self.session.window_index:
            self._guarded(lambda: self.session.set_window(index))()
        self._sync_sliders()
        self.refresh()

    # Key actions (named in the key table) -------------------------------------------------
    def toggle_pause(self) -> None:
        self.session.playback.paused = not self.session.playback.paused

    def step(self) -> None:
        """Pause and advance by one step unit."""
        self.session.playback.paused = True
        self.session.step()

    def cycle_step_unit(self) -> None:
        display = self.session.display
        display.step_unit = next_choice(step_units(self.session.config), display.step_unit)

    def reset(self) -> None:
        self.session.restart()

    def faster(self) -> None:
        self.session.playback.set_speed(self.session.playback.speed * 2.0)
        self._sync_sliders()

    def slower(self) -> None:
        self.session.playback.set_speed(self.session.playback.speed / 2.0)
        self._sync_sliders()

    def cycle_window(self) -> None:
        self.session.set_window((self.session.window_index + 1) % len(WINDOWS))
        self._sync_sliders()

    def cycle_pattern_colour(self) -> None:
        display = self.session.display
        display.pattern_colour = next_choice(pattern_colours(self.session.config), display.pattern_colour)
        self.session.recolour()

    def cycle_scene_colour(self) -> None:
        display = self.session.display
        display.scene_colour = next_choice(SCENE_COLOURS, display.scene_colour)
        self.session.recolour()

    def toggle_returns_model(self) -> None:
        """Cast with the ideal or the datasheet return model; the sliders show the return model's with the latter."""
        model = "ideal" if self.session.config.returns_model == "datasheet" else "datasheet"
        self.session.set_returns_model(model)
        if self.sliders is not None:
            self.sliders.page = "returns" if model == "datasheet" else "pattern"
            self._sync_sliders()
        returns = self.session.config.return_params
        self.session.message = (f"returns {model}" + (f": range noise {100 * returns.range_sigma_m[0][1]:g} cm, "
                                                      f"{returns.detection_range(0.1):.0f} m at 10 %"
                                                      if model == "datasheet" else ""))

    def toggle_slider_page(self) -> None:
        """Show the pattern's sliders or the return model's under the pattern view."""
        if self.sliders is not None:
            self.sliders.page = next_choice(SLIDER_PAGES, self.sliders.page)
            self._sync_sliders()
            self.session.message = f"sliders: {self.sliders.page}"

    def toggle_jitter_scope(self) -> None:
        self.session.set_jitter_scope("figure" if self.session.config.jitter_scope == "flower" else "flower")

    def toggle_pattern_model(self) -> None:
        """Switch between RflySim's rosette and the track (Risley or general) of the same configuration."""
        config = self.session.config
        if config.pattern_model != "rflysim":
            model = "rflysim"
        elif config.track is not None:
            model = "track"
        elif config.risley is not None:
            model = "risley"
        else:
            raise LivoxVizError("this configuration has no Risley track; load one with n/b "
                                "(e.g. livox_mid70_risley or livox_horizon) or --preset")
        self.session.set_config(config.with_pattern_model(model))
        self.session.message = f"pattern model {model}"

    def toggle_cloud_frame(self) -> None:
        """World or sensor accumulation of the cloud; the window is cast again in the new way."""
        display = self.session.display
        display.cloud_frame = next_choice(CLOUD_FRAMES, display.cloud_frame)
        if self.session.trajectory is not None:  # a sensor that stays puts its points in the same places either way
            self.session.set_window(self.session.window_index)
        self.session.message = f"cloud in the {display.cloud_frame} frame"

    def cycle_drawing(self) -> None:
        """Pattern view: density image when points outnumber pixels (auto), always points, always density."""
        self.session.display.drawing = next_choice(DRAWINGS, self.session.display.drawing)

    def cycle_scene(self) -> None:
        """The next scene: the shipped ones, then mesh files in the user's scenes folder.

        A file that does not load leaves the current scene and says why; the next press moves on.
        """
        from livox_viz.scene.scenes import open_scene, scene_choices

        choices = scene_choices()
        if self._scene_cursor < 0:
            names = [Path(c).name if os.sep in c else c for c in choices]
            self._scene_cursor = names.index(self.session.scene.name) if self.session.scene.name in names else -1
        self._scene_cursor = (self._scene_cursor + 1) % len(choices)
        scene = open_scene(choices[self._scene_cursor], **self.session.scene_options)
        self.session.set_scene(scene)
        self.session.message = f"scene {scene.name}"

    def _require_reference(self) -> None:
        if self.session.overlay.source is None:
            raise LivoxVizError("no reference: press e to pick a Risley preset, or start with --reference "
                                "FILE|PRESET")

    def toggle_reference(self) -> None:
        """Show or hide the reference overlay."""
        self._require_reference()
        self.session.overlay.visible = not self.session.overlay.visible

    def cycle_reference_window(self) -> None:
        """The overlay's own integration window."""
        self._require_reference()
        overlay = self.session.overlay
        overlay.set_window((overlay.window_index + 1) % len(WINDOWS), self.session.scan_time)

    def reference_choices(self) -> list[str]:
        """What ``e`` cycles through: the shipped and user presets with a track, in the pattern's plane.

        Kept until a preset file is added, removed or changed (reading and checking every preset took 250 ms
        of each press).
        """
        from livox_viz import load_preset
        from livox_viz.config.presets import shipped_preset_dir, user_preset_dir

        plane = self.session.config.pattern_plane
        files = []
        for folder in (shipped_preset_dir(), user_preset_dir()):
            try:
                files += [(entry.path, entry.stat().st_mtime_ns) for entry in os.scandir(folder)
                          if entry.name.endswith(".json")]
            except OSError:
                continue
        key = (plane, tuple(sorted(files)))
        if self._reference_choices is not None and self._reference_choices[0] == key:
            return list(self._reference_choices[1])
        choices = []
        for info in list_presets():
            try:
                config = load_preset(info.path)
            except LivoxVizError:
                continue
            if config.pattern_model != "rflysim" and config.pattern_plane == plane:
                choices.append(info.name)
        self._reference_choices = (key, choices)
        return list(choices)

    def cycle_reference(self) -> None:
        """The next reference: each preset with a Risley track in turn, then none."""
        from livox_viz import load_preset

        choices = [*self.reference_choices(), None]
        current = self.session.overlay.source
        name = current.name if isinstance(current, PresetSource) else None
        chosen = next_choice(choices, name if name in choices else None)
        source = None if chosen is None else PresetSource(load_preset(chosen), chosen, self.session.seed)
        self.session.overlay.set_source(source, self.session.scan_time)
        self.session.message = f"reference {chosen}" if chosen else "no reference"

    def fit_to_reference(self) -> None:
        """Fit the rosette's parameters to the reference's track on a worker, and move the sliders there when it is
        done (:meth:`finish_fit`; each tick looks): a fit takes 10-25 s, which the window plays on through."""
        from livox_viz.fitting.reference import pattern_table
        from livox_viz.fitting.rosette_fit import fit_reference

        self._require_reference()
        if self._fit is not None:
            self.session.message = f"fitting to {self._fit[1]} already (started {self._fit_age():.0f} s ago)"
            return
        source = self.session.overlay.source
        base = self.session.config.with_pattern_model("rflysim")
        # A daemon thread, not a pool's: quitting during a fit must not wait up to 25 s for it.
        future: Future = Future()

        def run() -> None:
            future.set_running_or_notify_cancel()
            try:
                table = source.table if isinstance(source, TableSource) else pattern_table(
                    source.config, source.name, 4.0, source.seed)
                future.set_result(fit_reference(table, base=base))
            except BaseException as exc:  # handed to finish_fit, which says it in the window
                future.set_exception(exc)

        threading.Thread(target=run, daemon=True, name="livox-viz-fit").start()
        self._fit = (future, source.name, time.perf_counter())
        self.session.message = f"fitting the rosette to {source.name} (10-25 s; the window plays on)"

    def _fit_age(self) -> float:
        return time.perf_counter() - self._fit[2] if self._fit is not None else 0.0

    def finish_fit(self, wait: bool = True) -> bool:
        """Apply a fit that :meth:`fit_to_reference` started, waiting for it (or, with ``wait`` false, only if it is
        done); whether one was applied. A fit that failed says why in the window."""
        if self._fit is None or not (wait or self._fit[0].done()):
            return False
        future, name, _ = self._fit
        seconds = self._fit_age()
        self._fit = None
        try:
            result = future.result()
        except (LivoxVizError, OSError) as exc:
            self.session.message = f"fit to {name} failed: {exc}"
            return False
        self.session.set_config(result.config, f"fitted-to-{name}")
        self.session.message = f"fitted to {name} in {seconds:.1f} s: shape rms {result.shape.rms_deg:.3f} deg"
        return True

    def toggle_help(self) -> None:
        self.hud.help_visible = not self.hud.help_visible

    def reset_cameras(self) -> None:
        for view in (self.pattern_view, self.scene_view):
            if view is not None:
                view.reset_camera()

    # Files ------------------------------------------------------------------------------
    def save_screenshot(self, folder: Path | None = None) -> Path:
        """Save the window as PNG with a JSON sidecar (configuration, seed, scan time, cameras); returns when
        both are written."""
        path = files.unused_screenshot_path(Path(folder) if folder is not None else self.screenshot_dir)
        files.write_png(self._current_image(), path)
        files.write_sidecar(path, files.sidecar(self.session, self.cameras(), self.plotter.window_size))
        self.session.message = f"saved {path}"
        return path

    def take_screenshot(self) -> Path:
        """The ``s`` key: capture the window now; a writer thread encodes the PNG and writes the sidecar.

        Encoding 1600x900 pixels takes 70-250 ms here, which the window would otherwise stand still for. The
        message says "saving", then "saved" (or why not); :meth:`close` waits for the files.
        """
        path = files.unused_screenshot_path(self.screenshot_dir)
        image = self._current_image()
        data = files.sidecar(self.session, self.cameras(), self.plotter.window_size)
        if self._writer is None:
            self._writer = ThreadPoolExecutor(1, thread_name_prefix="livox-viz-screenshot")
        self.session.message = f"saving {path}"
        self._writer.submit(self._write_screenshot, image, path, data)
        return path

    def _current_image(self) -> Any:
        """The window as it is now, what the sidecar describes: brought up to date and rendered first (pyvista's
        screenshot renders only on its first call, so keys pressed since the last tick were not in the picture)."""
        self.refresh()
        self.render()
        return self.plotter.screenshot(None, return_img=True)

    def _write_screenshot(self, image: Any, path: Path, data: dict[str, Any]) -> None:
        # On the writer thread: whatever stops the files is said in the window, never lost with the thread.
        try:
            files.write_png(image, path)
            files.write_sidecar(path, data)
        except LivoxVizError as exc:
            self.session.message = f"screenshot not saved: {exc}"
            return
        except OSError as exc:
            self.session.message = f"screenshot not saved: {path}: {exc.strerror or exc}"
            return
        self.session.message = f"saved {path}"

    def cameras(self) -> dict[str, Any]:
        """Each view's camera, for the sidecar."""
        cameras = {}
        for name, view in (("pattern", self.pattern_view), ("scene", self.scene_view)):
            if view is not None:
                camera = view.renderer.camera
                cameras[name] = {"position": list(camera.position), "focal_point": list(camera.focal_point),
                                 "up": list(camera.up), "parallel_scale": camera.parallel_scale,
                                 "view_angle": camera.view_angle}
        return cameras

    def save_preset(self) -> Path:
        """Write the current configuration as a user preset (never over a shipped one)."""
        path = files.save_user_preset(self.session)
        self.session.message = f"saved preset {path.stem}"
        return path

    def next_preset(self) -> None:
        self.cycle_preset(1)

    def previous_preset(self) -> None:
        self.cycle_preset(-1)

    def cycle_preset(self, direction: int) -> None:
        """Load the next (or previous) preset; an invalid one leaves the current configuration and says why."""
        presets = list_presets()
        names = [p.name for p in presets]
        if self._preset_cursor < 0 and self.session.preset_name in names:
            self._preset_cursor = names.index(self.session.preset_name)
        self._preset_cursor = (self._preset_cursor + direction) % len(presets)
        info = presets[self._preset_cursor]
        self.session.set_config(load_config(info.path), info.name)
        self.session.message = f"preset {info.name}"

    # Drawing ----------------------------------------------------------------------------
    def tick(self, now: float | None = None) -> None:
        """One timer tick: advance the scan by the wall time passed, apply a fit that is done, redraw."""
        self.session.tick(now)
        self.finish_fit(wait=False)
        self.refresh()

    def refresh(self) -> None:
        """Bring every actor and text up to date with the session (no render)."""
        if not self._ready:
            return
        for view in (self.pattern_view, self.scene_view, self.charts):
            if view is not None:
                view.update()
        self.hud.update(self.session, show_scene=self.scene_view is not None)

    def render(self) -> None:
        """Render once and update the frames-per-second figure."""
        self.plotter.ren_win.Render()
        now = time.perf_counter()
        if self._last_render is not None:
            instant = 1.0 / max(now - self._last_render, 1e-6)
            self.hud.fps = instant if self.hud.fps == 0 else 0.8 * self.hud.fps + 0.2 * instant
        self._last_render = now

    def show(self, stop: Callable[[], bool] | None = None) -> None:
        """Open the window and play until it is closed, or until ``stop()`` is true (checked every tick).

        A signal must not raise inside VTK's event loop (VTK swallows the
        exception and the window plays on): the caller notes it and ``stop``
        reports it, so the window closes on the next tick.
        """
        iren = self.plotter.iren
        iren.add_observer("TimerEvent", lambda *_: self._on_timer(stop))
        iren.create_timer(TIMER_MS, repeating=True)
        try:
            self.plotter.show(auto_close=True)
        finally:
            if self._writer is not None:  # the screenshots taken last are written before the command returns
                self._writer.shutdown(wait=True)

    def _on_timer(self, stop: Callable[[], bool] | None = None) -> None:
        if stop is not None and stop():
            self.plotter.iren.terminate_app()
            return
        try:
            self.tick()
        except LivoxVizError as exc:
            self.session.message = str(exc)
        self.render()

    def close(self) -> None:
        """Close the window once the screenshots being written are on disk."""
        if self._writer is not None:
            self._writer.shutdown(wait=True)
            self._writer = None
        self._fit = None  # a fit still running is not waited for: its result is not wanted any more
        if self.charts is not None:
            self.charts.close()
        self.plotter.close()


_OUR_CHARACTERS = {key for row in KEYS for key, _ in row.bindings if len(key) == 1}


def _swallow_our_keys(interactor, _event: str) -> None:
    if interactor.GetKeyCode() in _OUR_CHARACTERS:
        interactor.SetKeyCode("\0")


def render_offscreen(session: Session, seconds: float, path: Path, views: str = "both",
                     size: tuple[int, int] = (1600, 900)) -> Path:
    """Render what the GUI shows after ``seconds`` of scan time into a PNG (atomic)."""
    app = LivoxVizApp(session, off_screen=True, window_size=size, views=views)
    try:
        session.playback.paused = True
        session.advance_to(seconds)
        app.refresh()
        if app.charts is not None:
            app.charts.finish()  # the reference's curves are computed on a worker: the picture shows them
        app.render()
        files.write_png(app.plotter.screenshot(None, return_img=True), path)
    finally:
        app.close()
    return path


def display_problem(environ: Mapping[str, str] | None = None, timeout: float = 3.0) -> str | None:
    """Why no window can be opened here, in words; None when one can.

    VTK's window on Linux is an X11 window: it needs a ``DISPLAY`` whose X
    server answers (a Wayland session offers one through XWayland). The
    server is asked once, as VTK would ask it, in a thread given ``timeout``
    seconds (a forwarded display whose tunnel is gone may never answer).

    Parameters
    ----------
    environ : mapping, optional
        The environment to read (default ``os.environ``).
    timeout : float
        Seconds to wait for the X server.
    """
    environ = os.environ if environ is None else environ
    if sys.platform in ("win32", "darwin"):
        return None  # VTK opens native windows there
    display = environ.get("DISPLAY", "")
    if not display:
        wayland = environ.get("WAYLAND_DISPLAY")
        if wayland:
            return (f"only WAYLAND_DISPLAY={wayland} is set, and the window needs X11: run it under XWayland "
                    "with DISPLAY set")
        return "DISPLAY is not set"
    return _x11_problem(display, timeout)


def _x11_problem(display: str, timeout: float) -> str | None:
    name = ctypes.util.find_library("X11")
    if name is None:
        return None  # cannot ask: let VTK try
    try:
        xlib = ctypes.CDLL(name)
    except OSError:
        return None
    xlib.XOpenDisplay.restype = ctypes.c_void_p
    xlib.XOpenDisplay.argtypes = [ctypes.c_char_p]
    xlib.XCloseDisplay.argtypes = [ctypes.c_void_p]
    answer: list[bool] = []

    def ask() -> None:
        connection = xlib.XOpenDisplay(display.encode())
        if connection:
            xlib.XCloseDisplay(connection)
        answer.append(bool(connection))

    asking = threading.Thread(target=ask, daemon=True, name="x11-display-check")
    asking.start()
    asking.join(timeout)
    if not answer:
        return f"cannot open the display {display}: its X server did not answer within {timeout:g} s"
    if not answer[0]:
        return f"cannot open the display {display}: no X server answers there, or it refused us"
    return None

