"""The window with a million points (issue 19), off-screen through Mesa (software GL), 1600x900.

The session holds 1 000 000 points in the unlimited window (10 s of the
default preset in the urban scene), both views and the charts shown, as a
user sees them. Printed, each the best of several runs with the window filled
again before each:

1. One render of the window and the frame rate of playback (a tick of our
   work plus a render), for the drawings the views can use.
2. A slider change to its first frame drawn (rosette and Risley): our own
   work, then the render (target: our work <= 100 ms).
3. Every key: our own work (the action and the refresh of every actor), then
   the render (target <= 100 ms; the fit and the scene switch are
   computations a user starts, reported apart).
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from livox_viz.widgets.app import LivoxVizApp
from livox_viz.widgets.keys import KEYS
from livox_viz.widgets.overlay import WINDOWS
from livox_viz.widgets.session import Session

from livox_viz import load_preset
from livox_viz.scene.raycast import EmbreeCaster
from livox_viz.scene.scenes import open_scene

SIZE = (1600, 900)
REPEATS = 2
#: Keys that start a long computation or load a file, reported apart.
COMPUTATIONS = {"fit_to_reference", "cycle_scene"}


def filled(preset: str = "livox_mid70", reference: bool = False) -> tuple[Session, LivoxVizApp]:
    """A window holding a million points (paused, as after a user stopped to look)."""
    urban = open_scene("urban")
    session = Session(load_preset(preset), urban, seed=0, preset_name=preset, caster=CASTER)
    app = LivoxVizApp(session, off_screen=True, window_size=SIZE, views="both", screenshot_dir=SCREENSHOTS)
    if reference:
        app.cycle_reference()
    session.set_window(WINDOWS.index(None))
    for second in range(1, 11):  # a tick adds at most 400 000 points
        session.advance_to(float(second))
    session.playback.paused = True
    app.refresh()
    app.render(every=True)
    return session, app


def timed(action: Callable[[], None]) -> float:
    start = time.perf_counter()
    action()
    return time.perf_counter() - start


class _RenderClock:
    seconds = 0.0


def rendering_inside(app: LivoxVizApp) -> _RenderClock:
    """Count the time the views' plotters spend rendering from now on (a key that renders, such as the
    screenshot)."""
    clock = _RenderClock()

    def timed_by_clock(plain):
        def call(*args, **kwargs):
            start = time.perf_counter()
            try:
                return plain(*args, **kwargs)
            finally:
                clock.seconds += time.perf_counter() - start

        return call

    # The views' renders and the pixels read back for a screenshot: GL's time, not ours.
    app.render = timed_by_clock(app.render)
    for plotter in app.plotters.values():
        plotter.render = timed_by_clock(plotter.render)
        plotter.screenshot = timed_by_clock(plotter.screenshot)
    return clock


def render_costs() -> None:
    session, app = filled()
    views = {name: min(timed(plotter.ren_win.Render) for _ in range(REPEATS)) for name, plotter in app.plotters.items()}
    render = views["pattern"] + views["scene"]  # the charts are drawn only when they change
    print(f"window {SIZE[0]}x{SIZE[1]}, {session.pattern_ring.count:,} points in the pattern view "
          f"({'density image' if app.pattern_view.density_shown() else 'points'}), "
          f"{session.scene_ring.count:,} in the scene: a frame's render {render * 1e3:.0f} ms (pattern "
          f"{views['pattern'] * 1e3:.0f}, scene {views['scene'] * 1e3:.0f}; the charts {views['charts'] * 1e3:.0f} "
          "when they change)")
    session.playback.paused = False
    session.playback.set_speed(1.0)

    def tick() -> None:
        session.advance_to(session.scan_time + 0.033)  # one timer tick at real time: 3 300 points
        app.refresh()

    work = min(timed(tick) for _ in range(REPEATS))
    print(f"  playback at real time: our work {work * 1e3:.1f} ms a tick + the render -> "
          f"{1.0 / (work + render):.1f} frames/s under software GL")
    app.close()


def slider_to_first_frame(preset: str, name: str, values: list[float]) -> None:
    works, renders = [], []
    for value in values:
        session, app = filled(preset)

        def change(value: float = value, session: Session = session, app: LivoxVizApp = app) -> None:
            app.on_param(name, value)
            session.step("frame")
            app.refresh()

        works.append(timed(change))
        renders.append(timed(app.render))
        app.close()
    print(f"slider {name} ({preset}) -> first frame drawn, from a million points: our work "
          f"{min(works) * 1e3:.0f} ms (target <= 100), then the render {min(renders) * 1e3:.0f} ms")


def keys() -> None:
    worst = ("", 0.0)
    rows = []
    for row in KEYS:
        for key, method in row.bindings:
            if not hasattr(LivoxVizApp, method):
                continue  # the window's own (help, quit): Qt's, not ours
            works, renders = [], []
            for _ in range(REPEATS if method not in COMPUTATIONS else 1):
                _, app = filled(reference=method in {"toggle_reference", "cycle_reference_window",
                                                     "fit_to_reference"})
                action = getattr(app, method)
                inside = rendering_inside(app)
                # What the key's shortcut calls; a screenshot renders: that is GL's time, not ours.
                works.append(timed(lambda action=action, app=app: app.guarded(action)) - inside.seconds)
                renders.append(timed(app.render))
                app.close()
            work = min(works)
            rows.append((key, method, work, min(renders)))
            if method not in COMPUTATIONS and work > worst[1]:
                worst = (key, work)
    print("keys, from a million points in the window: our work / the render after it, ms")
    print("  " + "  ".join(f"{key} {work * 1e3:.0f}/{render * 1e3:.0f}" for key, method, work, render in rows
                           if method not in COMPUTATIONS))
    print(f"  slowest: {worst[0]} {worst[1] * 1e3:.0f} ms (target <= 100); started computations: "
          + ", ".join(f"{key} ({method}) {work * 1e3:.0f} ms" for key, method, work, _ in rows
                      if method in COMPUTATIONS))


if __name__ == "__main__":
    with tempfile.TemporaryDirectory() as folder:
        SCREENSHOTS = Path(folder) / "shots"
        os.environ["LIVOX_VIZ_PRESETS"] = str(Path(folder) / "presets")
        CASTER = EmbreeCaster(open_scene("urban").mesh)
        render_costs()
        slider_to_first_frame("livox_mid70", "petal_height", [3.0, 3.4, 3.8])
        slider_to_first_frame("livox_mid70_risley", "prism_rpm_a", [4000.0, 4100.0, 4200.0])
        keys()
