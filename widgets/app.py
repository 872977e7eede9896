"""The window's controller: it wires the session to the views, and does what keys, menus and the panel ask.

The controller is thin and knows no Qt: every parameter control calls
:meth:`LivoxVizApp.on_param` (name, value), which asks the
:class:`~livox_viz.widgets.session.Session` for the new configuration; the
session tells the views (they subscribe). Each view draws into a plotter of
its own: a Qt interactor in the window
(:mod:`~livox_viz.widgets.mainwindow`), an off-screen plotter in ``render``
and the tests, so both show the same pictures from the same code. Keys and
menus call the methods named in the one key table,
:mod:`livox_viz.widgets.keys`.
"""

from __future__ import annotations

import math
import os
import threading
import time
from collections.abc import Callable, Mapping
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import pyvista as pv

from livox_viz import LivoxVizError, SensorConfig, list_presets, load_config
from livox_viz.config.sensor import PARAM_RANGES
from livox_viz.core.blas import blas_threads

from . import files
from .cameras import PROJECTIONS, CameraState
from .charts import CurveCharts
from .colour_range import parse_colour_range, range_words
from .filters import CloudFilter
from .hud import HeadsUp
from .overlay import WINDOWS, PresetSource, TableSource
from .picks import pick_measures, status_line
from .playback import next_choice
from .session import CLOUD_FRAMES, DRAWINGS, SCENE_COLOURS, Session, pattern_colours, step_units
from .views import BACKGROUNDS, CAMERA_PRESETS, PatternView, SceneView, display_points

#: The parts of a window, left to right, and their share of its width in an off-screen picture of all of them.
VIEW_NAMES: tuple[str, ...] = ("pattern", "scene", "charts")
VIEW_WEIGHTS: dict[str, int] = {"pattern": 5, "scene": 4, "charts": 3}
#: Pixels a click may be from a drawn point and still pick it, measured on the screen (as CloudCompare's point
#: picking does): VTK's point picker measured at the focal plane, and a click on empty sky picked a point 230 px off.
PICK_TOLERANCE_PX = 5.0
#: What a click that picks nothing says.
NOTHING_PICKED = f"no point under the cursor (a click picks a point drawn within {PICK_TOLERANCE_PX:g} px of it)"
#: The pages of the parameter panel: the pattern model's parameters or the return model's.
PANEL_PAGES: tuple[str, ...] = ("pattern", "returns")


def quiet_vtk() -> None:
    """Silence VTK's own logging (its off-screen renders warn about the missing X server on every start)."""
    from vtkmodules.vtkCommonCore import vtkLogger, vtkObject

    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_OFF)
    vtkObject.GlobalWarningDisplayOff()


def view_sizes(views: str, size: tuple[int, int]) -> dict[str, tuple[int, int]]:
    """Each part's pixels in an off-screen picture of ``views`` (``"both"``: pattern, scene and charts side by
    side, :data:`VIEW_WEIGHTS` of the width; one view: all of it)."""
    if views != "both":
        return {views: size}
    width, height = size
    total = sum(VIEW_WEIGHTS.values())
    widths = [width * VIEW_WEIGHTS[name] // total for name in VIEW_NAMES]
    widths[0] += width - sum(widths)
    return {name: (w, height) for name, w in zip(VIEW_NAMES, widths, strict=True)}


def offscreen_plotter(size: tuple[int, int]) -> pv.Plotter:
    """An off-screen plotter for one view, as the window's are set up (no multisampling: it costs a factor of 3 on
    a million points in software GL)."""
    plotter = pv.Plotter(off_screen=True, window_size=size, title="livox-viz")
    plotter.ren_win.SetMultiSamples(0)
    plotter.ren_win.LineSmoothingOn()
    return plotter


class LivoxVizApp:
    """The controller of the views.

    Parameters
    ----------
    session : Session
    off_screen : bool
        Make off-screen plotters for the views (tests, ``livox-viz render``); the window passes its own
        ``plotters`` instead.
    window_size : tuple of int
        Pixels of all the views together, for off-screen plotters.
    views : {"both", "pattern", "scene"}
        ``both`` is pattern, scene and charts; one view alone is for renders.
    screenshot_dir : Path
        Where a screenshot goes.
    plotters : dict, optional
        ``{"pattern": plotter, "scene": plotter, "charts": plotter}`` (those of ``views``): the window's own.
    """

    def __init__(self, session: Session, off_screen: bool = True, window_size: tuple[int, int] = (1600, 900),
                 views: str = "both", screenshot_dir: Path = files.SCREENSHOT_DIR,
                 plotters: Mapping[str, pv.BasePlotter] | None = None) -> None:
        if views not in ("both", "pattern", "scene"):
            raise LivoxVizError(f"view {views!r}; allowed: both, pattern, scene")
        if plotters is None:
            if not off_screen:
                raise LivoxVizError("an on-screen window needs its plotters (livox_viz.widgets.mainwindow)")
            quiet_vtk()
            plotters = {name: offscreen_plotter(size) for name, size in view_sizes(views, window_size).items()}
        self.session = session
        self.views = views
        self.plotters = dict(plotters)
        self.screenshot_dir = Path(screenshot_dir)
        self.pattern_view = PatternView(plotters["pattern"], session) if "pattern" in plotters else None
        self.scene_view = SceneView(plotters["scene"], session) if "scene" in plotters else None
        self.charts = CurveCharts(plotters["charts"], (0, 0), session) if "charts" in plotters else None
        self.hud = HeadsUp(plotters.get("pattern"), plotters.get("scene"))
        #: The parameter panel's page: the pattern model's parameters or the return model's.
        self.page = "pattern"
        #: The picks in the scene view, in the order made (any number: the Picks panel lists them), and the last
        #: answer of any pick, in words.
        self.picks: list[dict[str, Any]] = []
        #: Rows of :attr:`picks` selected in the Picks panel (their dots ringed in the scene view).
        self.selected_picks: list[int] = []
        self.pick_text = ""
        #: Called after the picks changed (a pick, a removal, forgotten at a restart): the Picks panel follows.
        self.on_picks_change: Callable[[], None] | None = None
        self._picks_scan = session.scan_number
        #: ``defer(stages, action, what, kind) -> bool``: True when the compiled loops of ``stages`` are loaded (the
        #: action runs now); otherwise the window keeps ``action`` for when they are, says so, and returns False.
        #: None runs every action at once (renders and tests compile what they need on first use).
        self.defer: Callable[[set[str], Callable[[], None], str, str], bool] | None = None
        #: Called after a change the parameter panel must follow (the configuration or its page).
        self.on_panel_change: Callable[[], None] | None = None
        session.subscribe(self._on_change)
        self._last_render: float | None = None
        self.fps = 0.0
        self._writer: ThreadPoolExecutor | None = None  # screenshots being written
        self._fit: tuple[Future, str, float] | None = None  # the f key's fit running: its future, reference, start
        self._reference_choices: tuple[tuple, list[str]] | None = None
        # Find numpy's BLAS now (80 ms among the VTK libraries), not in the first key that makes a Risley track.
        blas_threads()
        self._preset_cursor = -1
        self._scene_cursor = -1
        #: The last table shown as the reference (``--reference`` or File > Open): ``e`` offers it again in turn.
        self._table_reference: TableSource | None = None
        self._ready = True
        self.refresh()

    def _on_change(self, what: str) -> None:
        if what == "config" and self.on_panel_change is not None:
            self.on_panel_change()

    def guarded(self, action: Callable[[], Any]) -> str | None:
        """Run a key's or menu's action: bad input becomes the session's message, never a crash. The message when
        the action was refused, else None."""
        try:
            action()
        except (LivoxVizError, ValueError) as exc:
            self.session.message = str(exc)
        except OSError as exc:
            where = f"{exc.filename}: " if exc.filename else ""
            self.session.message = f"{where}{exc.strerror or exc}"
        else:
            return None
        finally:
            self.refresh()
        return self.session.message

    # Applying a configuration ----------------------------------------------------------------
    def when_ready(self, stages: set[str], action: Callable[[], None], what: str = "", kind: str = "config") -> bool:
        """Run ``action`` now if the compiled loops of ``stages`` are loaded, else when they are (:attr:`defer`; one
        waits per ``kind``, the newest); whether it ran now."""
        if self.defer is not None and not self.defer(stages, action, what, kind):
            return False
        action()
        return True

    def apply_config(self, config: SensorConfig, preset_name: str | None = None, what: str = "") -> bool:
        """Show ``config`` now, or once the compiled loops it needs are loaded; whether it was applied now."""
        from livox_viz.casting.warm import stages_for

        return self.when_ready(stages_for(config, self.session.trajectory is not None),
                               lambda: self.session.set_config(config, preset_name), what)

    # Parameters --------------------------------------------------------------------------------
    def on_param(self, name: str, value: float) -> bool:
        """A parameter control changed: snap integers, validate, restart the pattern from the new configuration.

        A value outside the allowed range is refused with a message naming the range; the scan goes on with the
        old value. Returns whether the value was taken.
        """
        if not self._ready:
            return False
        if PARAM_RANGES[name].integer and math.isfinite(value):
            value = float(round(value))
        return self.session.set_param(name, value)

    def undo(self) -> None:
        """Give back the configuration before the last change (once its compiled loops are loaded)."""
        self._history_step("undo")

    def redo(self) -> None:
        """Make the last undone change again."""
        self._history_step("redo")

    def _history_step(self, word: str) -> None:
        from livox_viz.casting.warm import stages_for

        history = self.session.history
        target = history.undo_target() if word == "undo" else history.redo_target()
        if target is None:
            self.session.message = f"nothing to {word}"
            return
        step = self.session.undo if word == "undo" else self.session.redo
        self.when_ready(stages_for(target.config, self.session.trajectory is not None), step, word)

    def on_speed(self, speed: float) -> None:
        """The playback speed, in x real time."""
        taken = self.session.playback.set_speed(speed)
        # Said, as the integration window is: a refusal's red line stayed after a speed was taken.
        self.session.message = f"playback speed {taken:g} x real time"

    def on_window(self, index: int) -> None:
        """The integration window, an index into :data:`~livox_viz.widgets.overlay.WINDOWS`."""
        if index != self.session.window_index:
            self.session.set_window(index)

    def set_window_seconds(self, seconds: float | None) -> None:
        """The integration window as any number of seconds (0.01 to 10), or None for unlimited."""
        self.session.set_window_seconds(seconds)
        self.session.message = f"integration window {'unlimited' if seconds is None else f'{seconds:g} s'}"

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
        self.session.message = f"step unit: {display.step_unit}"

    def reset(self) -> None:
        self.session.restart()

    def faster(self) -> None:
        self.session.playback.set_speed(self.session.playback.speed * 2.0)

    def slower(self) -> None:
        self.session.playback.set_speed(self.session.playback.speed / 2.0)

    def cycle_window(self) -> None:
        index = self.session.window_index
        self.session.set_window(0 if index is None else (index + 1) % len(WINDOWS))

    def cycle_pattern_colour(self) -> None:
        display = self.session.display
        display.pattern_colour = next_choice(pattern_colours(self.session.config), display.pattern_colour)
        self.session.recolour()

    def cycle_scene_colour(self) -> None:
        display = self.session.display
        display.scene_colour = next_choice(SCENE_COLOURS, display.scene_colour)
        self.session.recolour()

    def set_pattern_colour(self, mode: str) -> None:
        if mode not in pattern_colours(self.session.config):
            raise LivoxVizError(f"pattern colour {mode!r}; allowed: {', '.join(pattern_colours(self.session.config))}")
        self.session.display.pattern_colour = mode
        self.session.recolour()

    def set_scene_colour(self, mode: str) -> None:
        if mode not in SCENE_COLOURS:
            raise LivoxVizError(f"scene colour {mode!r}; allowed: {', '.join(SCENE_COLOURS)}")
        self.session.display.scene_colour = mode
        self.session.recolour()

    def set_colour_range(self, low: str, high: str) -> tuple[float, float]:
        """Fix the scene colouring's range to ``low`` to ``high`` as typed (its unit; View > Colour range), checked
        by :func:`~livox_viz.widgets.colour_range.parse_colour_range`; the range taken."""
        mode = self.session.display.scene_colour
        bounds = parse_colour_range(mode, low, high)
        self.session.display.scene_colour_ranges[mode] = bounds
        self.session.message = f"the {mode} colouring's range: {range_words(mode, bounds)} (Automatic: the data's)"
        return bounds

    def automatic_colour_range(self) -> None:
        """The scene colouring spans the data's range again (View > Colour range > Automatic)."""
        mode = self.session.display.scene_colour
        self.session.display.scene_colour_ranges.pop(mode, None)
        low, high = self.session.scene_scalar_range()
        self.session.message = f"the {mode} colouring's range is automatic: {low:g} to {high:g} now"

    def set_returns_model(self, model: str) -> None:
        """Cast with the "ideal" or the "datasheet" return model; the panel shows the return model's sheet with the
        latter. The first datasheet use waits for its compiled loops (the window keeps playing meanwhile)."""
        if model == self.session.config.returns_model:
            return
        if self.session.source is not None:
            raise LivoxVizError("the live view draws the frames as the sender made them: its returns are the "
                                "sender's (a return model applies to the scan of the model, without --listen)")
        from livox_viz.casting.warm import stages_for

        config = self.session.config.with_returns_model(model)

        def switch() -> None:  # on the configuration in use when it runs (a preset may have come meanwhile)
            self.page = "returns" if model == "datasheet" else "pattern"
            self.session.set_config(self.session.config.with_returns_model(model))
            returns = self.session.config.return_params
            self.session.message = (f"returns {model}" + (f": range noise {100 * returns.range_sigma_m[0][1]:g} cm, "
                                                          f"{returns.detection_range(0.1):.0f} m at 10 %"
                                                          if model == "datasheet" else ""))

        self.when_ready(stages_for(config, self.session.trajectory is not None), switch, f"returns {model}", "returns")

    def toggle_returns_model(self) -> None:
        """Cast with the ideal or the datasheet return model."""
        self.set_returns_model("ideal" if self.session.config.returns_model == "datasheet" else "datasheet")

    def toggle_slider_page(self) -> None:
        """The panel shows the pattern's parameters or the return model's."""
        self.page = next_choice(PANEL_PAGES, self.page)
        self.session.message = f"parameters: {self.page}"
        if self.on_panel_change is not None:
            self.on_panel_change()

    def toggle_jitter_scope(self) -> None:
        from dataclasses import replace

        scope = "figure" if self.session.config.jitter_scope == "flower" else "flower"
        self.apply_config(replace(self.session.config, jitter_scope=scope))
        self.session.message = f"random rotation after each {scope}"

    def toggle_pattern_model(self) -> None:
        """Switch between RflySim's rosette and the track (Risley or general) of the same configuration."""
        from livox_viz.config.sensor import V3_MID360_TYPE_ID

        config = self.session.config
        if config.type_id == V3_MID360_TYPE_ID:
            raise LivoxVizError(f"RflySim's Mid-360 (TypeID {V3_MID360_TYPE_ID}) scans its own track and has no "
                                "rosette; allowed: v with a TypeID 6 or 22 configuration or a Risley or track preset")
        if config.pattern_model != "rflysim":
            model = "rflysim"
        elif config.track is not None:
            model = "track"
        elif config.risley is not None:
            model = "risley"
        else:
            raise LivoxVizError("this configuration has no Risley track; pick a preset that has one with n/b or "
                                "File > Open preset (e.g. livox_mid70_risley or livox_horizon)")
        if self.apply_config(config.with_pattern_model(model), None, f"pattern model {model}"):
            self.session.message = f"pattern model {model}"

    def toggle_cloud_frame(self) -> None:
        """World or sensor accumulation of the cloud; the window is cast again in the new way."""
        display = self.session.display
        if self.session.trajectory is None:
            self.session.message = ("w: the sensor does not move (no --trajectory), so the cloud is the same in the "
                                    "world and the sensor frame")
            return
        display.cloud_frame = next_choice(CLOUD_FRAMES, display.cloud_frame)
        self.session.set_window_seconds(self.session.window)
        self.session.message = f"cloud in the {display.cloud_frame} frame"

    def cycle_drawing(self) -> None:
        """Pattern view: density image when points outnumber pixels (auto), always points, always density."""
        self.session.display.drawing = next_choice(DRAWINGS, self.session.display.drawing)
        self.session.message = f"drawing: {self.session.display.drawing}"

    def cycle_scene(self) -> None:
        """The next scene: the shipped ones, then mesh files in the user's scenes folder.

        A file that does not load leaves the current scene and says why; the next press moves on.
        """
        from livox_viz.scene.scenes import open_scene

        choice = self.next_scene_choice()
        scene = open_scene(choice, **self.session.scene_options)
        self.session.set_scene(scene)
        self.session.sources["scene"] = choice
        self.session.message = f"scene {scene.name}"

    def next_scene_choice(self) -> str:
        """The scene ``m`` moves to: the one after the current among the shipped scenes and the user's meshes."""
        from livox_viz.scene.scenes import scene_choices

        choices = scene_choices()
        if self._scene_cursor < 0:
            names = [Path(c).name if os.sep in c else c for c in choices]
            self._scene_cursor = names.index(self.session.scene.name) if self.session.scene.name in names else -1
        self._scene_cursor = (self._scene_cursor + 1) % len(choices)
        return choices[self._scene_cursor]

    def _require_reference(self) -> None:
        if self.session.overlay.source is None:
            raise LivoxVizError("no reference: press e to pick a Risley preset, or File > Open shipped reference "
                                "table (or start with --reference FILE|PRESET)")

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
        found = []
        for folder in (shipped_preset_dir(), user_preset_dir()):
            try:
                found += [(entry.path, entry.stat().st_mtime_ns) for entry in os.scandir(folder)
                          if entry.name.endswith(".json")]
            except OSError:
                continue
        key = (plane, tuple(sorted(found)))
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
        """The next reference: the table last shown (if any), each preset with a track in turn, then none."""
        from livox_viz import load_preset

        current = self.session.overlay.source
        if isinstance(current, TableSource):
            self._table_reference = current
        table = self._table_reference
        # A trial found the table of --reference gone for good after one e: it is the first choice of the round.
        table_key = f"table {table.name}" if table is not None else None
        choices = [*([table_key] if table_key else []), *self.reference_choices(), None]
        name = table_key if isinstance(current, TableSource) else current.name if current is not None else None
        chosen = next_choice(choices, name if name in choices else None)
        if chosen is None:
            self.set_reference(None)
            return
        if chosen == table_key:
            self.set_reference(table)
            return
        from livox_viz.casting.warm import pattern_stages

        config = load_preset(chosen)
        # Only its pattern is played: the Avia's datasheet returns made it wait a minute for loops it never uses.
        self.when_ready(pattern_stages(config),
                        lambda: self.set_reference(PresetSource(config, chosen, self.session.seed)),
                        f"reference {chosen}", "reference")

    def set_reference(self, source: TableSource | PresetSource | None) -> None:
        """Overlay ``source`` (None: none) and fit the pattern view's camera to it."""
        if source is not None and source.plane != self.session.config.pattern_plane:
            raise LivoxVizError(f"reference {source.name} is a {source.plane} pattern and this configuration a "
                                f"{self.session.config.pattern_plane} one; allowed: a reference in the same plane")
        self.session.overlay.set_source(source, self.session.scan_time)
        self.session.message = f"reference {source.name}" if source is not None else "no reference"
        if source is not None and source.end is not None:
            self.session.message += (f" (a {source.end:.3g} s recording: drawn in step with the scan for its span, "
                                     "then its last window held)")
        if self.pattern_view is not None:
            self.pattern_view.reset_camera()

    def fit_to_reference(self) -> None:
        """Fit the rosette's parameters to the reference's track on a worker, and move the parameters there when it
        is done (:meth:`finish_fit`; each tick looks): a fit takes 10-25 s, which the window plays on through."""
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

    @property
    def fitting(self) -> str | None:
        """The reference a fit is running against, or None."""
        return self._fit[1] if self._fit is not None else None

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
        self.apply_config(result.config, f"fitted-to-{name}")
        self.session.message = f"fitted to {name} in {seconds:.1f} s: shape rms {result.shape.rms_deg:.3f} deg"
        rough = result.shape.rough_warning()
        if rough:  # applied all the same (Ctrl+Z undoes it): the user asked for the fit, and sees how far it is
            self.session.message += f"; warning: {rough}"
        return True

    def reset_cameras(self) -> None:
        """Both views' cameras back to fit everything drawn (the pattern view the reference too)."""
        for view in (self.pattern_view, self.scene_view):
            if view is not None:
                view.reset_camera()

    def set_scene_camera(self, preset: str) -> None:
        """The scene view's camera: one of :data:`~livox_viz.widgets.views.CAMERA_PRESETS`, or ``"follow"`` to move
        with the vehicle from where it is."""
        if self.scene_view is None:
            return
        if preset == "follow":
            self.scene_view.follow = not self.scene_view.follow
            self.session.message = ("the scene's camera follows the vehicle" if self.scene_view.follow
                                    else "the scene's camera stays where it is")
            return
        if preset not in CAMERA_PRESETS:
            raise LivoxVizError(f"camera {preset!r}; allowed: {', '.join(CAMERA_PRESETS)}, follow")
        self.scene_view.reset_camera(preset)

    # The scene view's projection, viewpoints and filter (issue 45 item 6) ------------------------------
    def set_projection(self, projection: str) -> None:
        """The scene view's projection, one of :data:`~livox_viz.widgets.cameras.PROJECTIONS`, what it looks at
        kept the same size."""
        if self.scene_view is None:
            return
        self.scene_view.set_projection(projection)
        hint = ": View > Scene camera > top makes it a map" if projection == "orthographic" else ""
        self.session.message = f"scene view {projection}{hint}"

    def toggle_projection(self) -> None:
        """Perspective / orthographic (the 5 key, as Blender's keypad 5)."""
        if self.scene_view is not None:
            self.set_projection(PROJECTIONS[1 - PROJECTIONS.index(self.scene_view.projection)])

    def scene_camera(self) -> CameraState:
        """The scene view's camera now (what View > Viewpoints > Save keeps)."""
        if self.scene_view is None:
            raise LivoxVizError("no scene view; allowed: the window with its scene view")
        return CameraState.of(self.scene_view.renderer.camera)

    def restore_scene_camera(self, state: CameraState, name: str = "") -> None:
        """Put the scene view's camera in ``state`` (a saved viewpoint called ``name``)."""
        if self.scene_view is None:
            return
        state.apply(self.scene_view.renderer.camera)
        self.scene_view.renderer.ResetCameraClippingRange()
        self.session.message = f"viewpoint {name!r} ({state.projection})" if name else f"{state.projection} view"

    def set_cloud_filter(self, cloud_filter: CloudFilter | None) -> None:
        """Draw only the scene's points inside ``cloud_filter``'s bounds (None: every point)."""
        if self.scene_view is None:
            return
        self.scene_view.cloud_filter = cloud_filter or CloudFilter()
        active = self.scene_view.cloud_filter
        self.session.message = (f"filter: {active.describe()} (points outside are not drawn or picked)"
                                if active.active else "filters cleared: every point of the cloud drawn")

    def clear_filters(self) -> None:
        self.set_cloud_filter(None)

    # Picking -------------------------------------------------------------------------------
    def _picks_changed(self) -> None:
        self.selected_picks = [row for row in self.selected_picks if row < len(self.picks)]
        if self.scene_view is not None:
            self.scene_view.mark_picks([p["xyz_world"] for p in self.picks])
            self._ring_selected_picks()
        if self.on_picks_change is not None:
            self.on_picks_change()

    def forget_opened_cloud_picks(self) -> None:
        """The opened cloud closed or replaced: if a pick was one of its points, the picks go (their numbers and
        measures run through it)."""
        if any("cloud" in pick for pick in self.picks):
            self.forget_picks()

    def select_picks(self, rows: list[int]) -> None:
        """The picks selected in the Picks panel (0-based rows): the scene view rings their dots."""
        if any(not 0 <= row < len(self.picks) for row in rows):
            raise LivoxVizError(f"no pick {max(rows) + 1}; allowed: 1 to {len(self.picks)}")
        self.selected_picks = sorted(set(rows))
        if self.scene_view is not None:
            self._ring_selected_picks()

    def _ring_selected_picks(self) -> None:
        assert self.scene_view is not None
        self.scene_view.mark_selected_picks([self.picks[row]["xyz_world"] for row in self.selected_picks])

    def forget_picks(self) -> None:
        """Drop the picks and their marks (the scan moved to another time: the points picked may not be there)."""
        self.picks = []
        self.pick_text = ""
        self._picks_changed()

    def clear_picks(self) -> None:
        """The Picks panel's Clear: every pick and its mark goes."""
        count = len(self.picks)
        self.forget_picks()
        self.session.message = f"{count} pick{'s' if count != 1 else ''} cleared" if count else "no picks to clear"

    def remove_last_pick(self) -> None:
        """The Picks panel's Remove last: the last pick and its mark go; the measures are those of the picks left."""
        if not self.picks:
            raise LivoxVizError("no pick to remove; allowed: once a point of the cloud is clicked")
        self.picks = self.picks[:-1]
        self.pick_text = status_line(self.picks) if self.picks else ""
        self._picks_changed()
        self.session.message = f"pick {len(self.picks) + 1} removed"

    def turn_about_last_pick(self) -> None:
        """The scene camera turns about the last pick from now on (ParaView's Pick Center); r gives the default
        back. Following the vehicle stops: it would carry the centre off the point."""
        if self.scene_view is None or not self.picks:
            raise LivoxVizError("no pick to turn about; allowed: once a point of the cloud is clicked in the scene "
                                "view")
        self.scene_view.turn_about(np.asarray(self.picks[-1]["xyz_world"], dtype=np.float64))
        stopped = ""
        if self.scene_view.follow:
            self.scene_view.follow = False
            stopped = "; it no longer follows the vehicle"
        self.session.message = (f"the scene camera turns about pick {len(self.picks)}{stopped} (r resets the "
                                "cameras)")

    def pick_scene(self, x_px: float, y_px: float) -> dict[str, Any] | None:
        """The cloud's point under the display position ``(x_px, y_px)`` of the scene view (VTK's pixels, origin
        bottom left), or None; it joins :attr:`picks`, and :attr:`pick_text` says its values and what it measures
        with the picks before (:func:`~livox_viz.widgets.picks.status_line`)."""
        view = self.scene_view
        if view is None:
            return None
        slot = view.drawn_point_at(x_px, y_px, PICK_TOLERANCE_PX)
        opened = view.opened_point_at(x_px, y_px, PICK_TOLERANCE_PX)
        if opened is not None and (slot is None or opened[1] < view.screen_distance_px(slot, x_px, y_px)):
            # The opened cloud's point is the nearer on the screen: it is picked, with what its file holds.
            assert view.opened is not None
            found = {"xyz_world": view.opened_point(opened[0]).tolist(), "xyz_sensor": None,
                     "cloud": view.opened[0], "index": opened[0]}
        elif slot is None:
            self.pick_text = NOTHING_PICKED
            return None
        else:
            found = self.session.scene_point(slot)
        self._picks_scan = self.session.scan_number
        self.picks = [*self.picks, found]
        measures = pick_measures(self.picks)
        if measures.distance_m is not None:
            found["distance_m"] = measures.distance_m
        self.pick_text = status_line(self.picks)
        self._picks_changed()
        return found

    def pick_pattern(self, x_px: float, y_px: float) -> dict[str, float] | None:
        """The pattern's sample nearest to the display position ``(x_px, y_px)`` of the pattern view, or None when
        none is drawn within :data:`PICK_TOLERANCE_PX` of it (a click outside the pattern named its nearest sample,
        however far)."""
        if self.pattern_view is None:
            return None
        view = self.pattern_view
        renderer = view.renderer
        renderer.SetDisplayPoint(x_px, y_px, 0.0)
        renderer.DisplayToWorld()
        world = renderer.GetWorldPoint()
        x_deg, y_deg = view.plane_point((world[0] / world[3], world[1] / world[3], 0.0))
        found = self.session.nearest_pattern_point(x_deg, y_deg, y_scale=view.stretch)
        if found is not None:
            xy, _ = display_points(renderer, np.array([[found["x_deg"], found["y_deg"] * view.stretch, 0.0]]))
            if math.hypot(xy[0, 0] - x_px, xy[0, 1] - y_px) > PICK_TOLERANCE_PX:
                found = None
        if found is None:
            self.pick_text = NOTHING_PICKED
            return None
        self.pick_text = (f"pattern point x {found['x_deg']:.3f} deg, y {found['y_deg']:.3f} deg, t "
                          f"{found['t_s']:.5f} s, sample {found['index']:,}")
        return found

    # Files ------------------------------------------------------------------------------
    def view_images(self) -> dict[str, np.ndarray]:
        """Each view's picture as it is now, brought up to date and rendered first (pyvista's screenshot renders
        only on its first call, so keys pressed since the last tick were not in the picture); the charts' curves
        being computed are waited for."""
        if self.charts is not None:
            self.charts.finish()
        self.refresh()
        self.render(every=True)
        return {name: np.asarray(plotter.screenshot(None, return_img=True))
                for name, plotter in self.plotters.items()}

    def current_image(self) -> np.ndarray:
        """The views side by side, left to right as in the window: what a screenshot holds.

        Each part's pixels are kept (:attr:`image_sizes`) for the sidecar: the images' own, not the render windows'
        sizes, which in the window lag a resize until its next paint.
        """
        images = self.view_images()
        parts = [(name, images[name]) for name in VIEW_NAMES if name in images]
        height = min(part.shape[0] for _, part in parts)
        self.image_sizes = {name: [int(part.shape[1]), int(height)] for name, part in parts}
        return np.concatenate([part[:height, :, :3] for _, part in parts], axis=1)

    def save_screenshot(self, folder: Path | None = None) -> Path:
        """Save the views as PNG with a JSON sidecar from which ``render --sidecar`` makes the same picture; returns
        when both are written."""
        path = files.unused_screenshot_path(Path(folder) if folder is not None else self.screenshot_dir).absolute()
        image = self.current_image()
        files.write_png(image, path)
        files.write_sidecar(path, self.sidecar())
        self.session.message = f"saved {path}"
        return path

    def take_screenshot(self) -> Path:
        """The ``s`` key: capture the views now; a writer thread encodes the PNG and writes the sidecar.

        Encoding 1600x900 pixels takes 70-250 ms here, which the window would otherwise stand still for. The
        message says "saving", then "saved" (or why not); :meth:`close` waits for the files.
        """
        # Said whole: "saved screenshots/..." told a user started from a shortcut nothing of where it went.
        path = files.unused_screenshot_path(self.screenshot_dir).absolute()
        image = self.current_image()
        data = self.sidecar()
        if self._writer is None:
            self._writer = ThreadPoolExecutor(1, thread_name_prefix="livox-viz-screenshot")
        self.session.message = f"saving {path}"
        self._writer.submit(self._write_screenshot, image, path, data)
        return path

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

    def sidecar(self) -> dict[str, Any]:
        """What a screenshot's sidecar holds: everything ``render --sidecar`` needs to draw the picture again."""
        sizes = getattr(self, "image_sizes", None) or {name: list(plotter.window_size)
                                                         for name, plotter in self.plotters.items()}
        return files.sidecar(self.session, self.drawing_state(), self.cameras(), sizes)

    def drawing_state(self) -> dict[str, Any]:
        """How the views draw beyond the session's own state: colour maps, point sizes, panel page, follow."""
        state: dict[str, Any] = {"panel_page": self.page}
        if self.pattern_view is not None:
            state["pattern"] = {"colour_map": self.pattern_view.colour_map, "point_size": self.pattern_view.point_size,
                                "background": self.pattern_view.background_name}
        if self.scene_view is not None:
            state["scene"] = {"colour_map": self.scene_view.colour_map, "point_size": self.scene_view.point_size,
                              "background": self.scene_view.background_name,
                              "follow": self.scene_view.follow, "grid": self.scene_view.grid_actor is not None,
                              "axes": self.scene_view.axes_actor is not None,
                              "filter": (self.scene_view.cloud_filter.to_json()
                                         if self.scene_view.cloud_filter.active else None),
                              "colour_ranges": {mode: list(bounds) for mode, bounds
                                                in self.session.display.scene_colour_ranges.items()}}
        return state

    def apply_drawing_state(self, state: Mapping[str, Any]) -> None:
        """The inverse of :meth:`drawing_state` (a sidecar's, for ``render --sidecar``)."""
        for name, view in (("pattern", self.pattern_view), ("scene", self.scene_view)):
            given = state.get(name)
            if view is None or not isinstance(given, Mapping):
                continue
            if given.get("colour_map"):
                view.set_colour_map(str(given["colour_map"]))
            if given.get("point_size"):
                view.set_point_size(float(given["point_size"]))
            # A sidecar without one (before it was kept) keeps the view's own: the white one was drawn dark again.
            background = given.get("background")
            if background is not None:
                if background not in BACKGROUNDS:
                    raise LivoxVizError(f"{name} view's background {background!r}; allowed: "
                                        f"{', '.join(BACKGROUNDS)}")
                view.set_background(str(background))
        scene = state.get("scene")
        if self.scene_view is not None and isinstance(scene, Mapping):
            self.scene_view.follow = bool(scene.get("follow", self.scene_view.follow))
            self.scene_view.show_grid(bool(scene.get("grid")))
            self.scene_view.show_axes(bool(scene.get("axes")))
            self.scene_view.cloud_filter = CloudFilter.from_json(scene.get("filter"))
            ranges = scene.get("colour_ranges") or {}
            if not isinstance(ranges, Mapping):
                raise LivoxVizError(f"the scene's colour_ranges {ranges!r}; allowed: {{colouring: [min, max]}}")
            for mode, bounds in ranges.items():
                if not (isinstance(bounds, (list, tuple)) and len(bounds) == 2):
                    raise LivoxVizError(f"the scene's colour range of {mode!r}: {bounds!r}; allowed: [min, max]")
                self.session.display.scene_colour_ranges[str(mode)] = parse_colour_range(
                    str(mode), str(bounds[0]), str(bounds[1]))

    def cameras(self) -> dict[str, Any]:
        """Each view's camera, for the sidecar (:meth:`CameraState.to_json`, as a saved viewpoint holds it)."""
        return {name: CameraState.of(view.renderer.camera).to_json()
                for name, view in (("pattern", self.pattern_view), ("scene", self.scene_view)) if view is not None}

    def apply_cameras(self, cameras: Mapping[str, Any]) -> None:
        """Put each view's camera where :meth:`cameras` found it (a camera that cannot be is refused in one line,
        before any view moves)."""
        states = {name: CameraState.from_json(given, f"the {name} view's camera") for name, given in cameras.items()
                  if name in ("pattern", "scene") and isinstance(given, Mapping)}
        for name, view in (("pattern", self.pattern_view), ("scene", self.scene_view)):
            if view is not None and name in states:
                states[name].apply(view.renderer.camera)
                view.renderer.ResetCameraClippingRange()

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
        if self.apply_config(load_config(info.path), info.name, f"preset {info.name}"):
            self.session.message = f"preset {info.name}"

    # Drawing ----------------------------------------------------------------------------
    def tick(self, now: float | None = None) -> None:
        """One timer tick: advance the scan by the wall time passed, apply a fit that is done, redraw."""
        self.session.tick(now)
        self.finish_fit(wait=False)
        self.refresh()

    def refresh(self) -> None:
        """Bring every actor and text up to date with the session (no render)."""
        if not getattr(self, "_ready", False):
            return
        if self._picks_scan != self.session.scan_number:
            # A restart (a preset, a parameter, a scene, x) began another scan: its points are not the ones picked.
            self._picks_scan = self.session.scan_number
            if self.picks or self.pick_text:
                self.forget_picks()
        for view in (self.pattern_view, self.scene_view, self.charts):
            if view is not None:
                view.update()
        self.hud.update(self.session, density_shown=self.pattern_view is not None and self.pattern_view.density_shown(),
                        drawn=self.scene_view.drawn_count() if self.scene_view is not None else 0,
                        opened=self.scene_view.opened_line() if self.scene_view is not None else "",
                        filtered=self.scene_view.filter_line() if self.scene_view is not None else "")

    def render(self, every: bool = False, draw: Callable[[pv.BasePlotter], None] | None = None) -> None:
        """Render the views (the charts only when they changed, or ``every``) and update the frames per second.

        ``draw(plotter)`` renders one view (default: its render window's ``Render``); the window passes Qt's
        repaint instead, as a direct render there is drawn twice (once more by the paint it schedules).
        """
        for name, plotter in self.plotters.items():
            if name == "charts" and not every and not (self.charts is not None and self.charts.dirty):
                continue
            if draw is None:
                plotter.ren_win.Render()
            else:
                draw(plotter)
            if name == "charts" and self.charts is not None:
                self.charts.dirty = False
        now = time.perf_counter()
        if self._last_render is not None:
            instant = 1.0 / max(now - self._last_render, 1e-6)
            self.fps = instant if self.fps == 0 else 0.8 * self.fps + 0.2 * instant
        self._last_render = now

    def close(self) -> None:
        """Close the views once the screenshots being written are on disk (nothing is refreshed after)."""
        self._ready = False
        if self._writer is not None:
            self._writer.shutdown(wait=True)
            self._writer = None
        self._fit = None  # a fit still running is not waited for: its result is not wanted any more
        if self.charts is not None:
            self.charts.close()
        for plotter in self.plotters.values():
            plotter.close()


def render_offscreen(session: Session, seconds: float, path: Path, views: str = "both",
                     size: tuple[int, int] = (1600, 900), sizes: Mapping[str, tuple[int, int]] | None = None,
                     prepare: Callable[[LivoxVizApp], None] | None = None) -> Path:
    """Render what the window shows after ``seconds`` of scan time into a PNG (atomic).

    Parameters
    ----------
    session : Session
    seconds : float
        Scan time of the picture.
    path : Path
    views : {"both", "pattern", "scene"}
    size : tuple of int
        Pixels of the whole picture.
    sizes : mapping, optional
        Each part's own pixels (a screenshot's sidecar), instead of ``size``'s split.
    prepare : callable, optional
        Called with the controller before the picture is drawn (cameras, drawing state).
    """
    if sizes is not None:
        quiet_vtk()
        plotters = {name: offscreen_plotter(tuple(int(v) for v in sizes[name])) for name in sizes}
        app = LivoxVizApp(session, views=views, plotters=plotters)
    else:
        app = LivoxVizApp(session, off_screen=True, window_size=size, views=views)
    try:
        session.seek(seconds)  # the window that ends there, exactly as a scan played to it holds it
        if prepare is not None:
            prepare(app)
        app.refresh()
        if app.charts is not None:
            app.charts.finish()  # the reference's curves are computed on a worker: the picture shows them
        files.write_png(app.current_image(), path)
    finally:
        app.close()
    return path
