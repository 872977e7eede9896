"""GUI update costs (issue: the interactive VTK GUI), off-screen through Mesa.

1. Adding one frame (10 000 points) to a pattern view that already holds
   1 000 000 points, against a bare re-render of the same 1 000 000 points in
   the same run (target <= 1.2 x).
2. A slider change to the first frame drawn of the new pattern: our own work
   on top of one render (target <= 50 ms).
3. The cost of our bookkeeping per tick with 100 000 and with 1 000 000 points
   in the window (flat means it does not grow with the points on screen).
4. The live charts: a slider change until both curves (coverage and radial
   density) of ours are redrawn, with 1 000 000 points in the window and a
   Risley reference shown, for the rosette and for the Risley model: our own
   work (target <= 100 ms), next to one render of the whole window.
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from livox_viz.widgets.app import LivoxVizApp
from livox_viz.widgets.overlay import WINDOWS
from livox_viz.widgets.session import Session

from livox_viz import load_preset
from livox_viz.scene.scenes import open_scene

REPEATS = 9


def median_time(action, repeats: int = REPEATS) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        action()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    session = Session(load_preset("livox_mid70"), open_scene("urban"), seed=0, preset_name="livox_mid70")
    app = LivoxVizApp(session, off_screen=True, window_size=(800, 800), views="pattern")
    session.set_window(WINDOWS.index(None))
    for second in range(1, 11):
        session.advance_to(float(second))
    session.display.drawing = "points"
    app.refresh()
    app.render()
    print(f"pattern view, 800x800 off-screen, {session.pattern_ring.count:,} points on screen, drawn as points")

    bare = median_time(app.plotter.ren_win.Render)

    def add_frame() -> None:
        session.advance_to(session.scan_time + 0.1)
        app.refresh()
        app.plotter.ren_win.Render()

    add = median_time(add_frame)
    print(f"  bare re-render of the same points: {bare * 1e3:7.1f} ms")
    print(f"  add one frame (10 000 pts) + render: {add * 1e3:7.1f} ms = {add / bare:.2f} x the bare render"
          " (target <= 1.2)")

    def bookkeeping() -> None:
        session.advance_to(session.scan_time + 0.1)
        app.refresh()

    ours_1m = median_time(bookkeeping)
    session.display.drawing = "auto"
    app.refresh()
    app.plotter.ren_win.Render()
    density_bare = median_time(app.plotter.ren_win.Render)
    density_add = median_time(add_frame)
    print(f"  as a density image (auto once points outnumber pixels): re-render {density_bare * 1e3:.1f} ms, "
          f"add one frame + render {density_add * 1e3:.1f} ms = {density_add / bare:.3f} x the bare points render")
    app.close()

    session = Session(load_preset("livox_mid70"), open_scene("urban"), seed=0, preset_name="livox_mid70")
    app = LivoxVizApp(session, off_screen=True, window_size=(800, 800), views="both")
    session.advance_to(0.5)
    app.refresh()
    app.render()
    render_only = median_time(app.plotter.ren_win.Render)
    heights = iter([3.0, 3.2, 3.4, 3.6, 3.8, 4.0, 4.2, 4.4, 4.6, 4.8])

    def slider_to_first_frame() -> None:
        app.on_param("petal_height", next(heights))
        session.step("frame")
        app.refresh()
        app.plotter.ren_win.Render()

    slider = median_time(slider_to_first_frame)
    print(f"slider change -> first frame drawn (both views): {slider * 1e3:.1f} ms, of which one render "
          f"{render_only * 1e3:.1f} ms: our own work {max(slider - render_only, 0) * 1e3:.1f} ms (target <= 50 ms)")
    app.close()

    session = Session(load_preset("livox_mid70"), open_scene("urban"), seed=0)
    app = LivoxVizApp(session, off_screen=True, window_size=(400, 400), views="pattern")
    session.set_window(WINDOWS.index(1.0))
    session.advance_to(1.0)
    session.advance_to(2.0)
    ours_100k = median_time(bookkeeping_for(session, app))
    print(f"our bookkeeping per tick (one frame, pattern + cast + ring + VTK arrays): "
          f"{ours_100k * 1e3:.1f} ms with 100 000 points on screen, {ours_1m * 1e3:.1f} ms with 1 000 000 "
          f"(ratio {ours_1m / ours_100k:.2f}; flat is 1)")
    app.close()


def bookkeeping_for(session: Session, app: LivoxVizApp):
    def run() -> None:
        session.advance_to(session.scan_time + 0.1)
        app.refresh()

    return run


def chart_cost(preset: str, name: str, values: list[float]) -> None:
    """Print the cost of slider changes of ``name`` to the redrawn curves, a million points in the window."""
    from livox_viz.widgets.overlay import PresetSource

    session = Session(load_preset(preset), open_scene("urban"), seed=0, preset_name=preset)
    app = LivoxVizApp(session, off_screen=True, window_size=(1600, 900), views="both")
    session.overlay.set_source(PresetSource(load_preset("livox_mid70_risley"), "livox_mid70_risley"), 0.0)
    session.set_window(WINDOWS.index(None))
    for second in range(1, 11):  # a tick adds at most 400 000 points
        session.advance_to(float(second))
    app.refresh()
    app.render()
    render = median_time(app.plotter.ren_win.Render)
    points = session.pattern_ring.count
    costs = []
    for value in values:
        for second in range(1, 11):  # the window holds a million points again before each change
            session.advance_to(float(second))
        start = time.perf_counter()
        app.on_param(name, value)
        costs.append(time.perf_counter() - start)
    app.close()
    print(f"charts, {preset}: slider {name} -> both curves redrawn, our work {statistics.median(costs) * 1e3:.1f} "
          f"ms (target <= 100 ms) with {points:,} points in the window; one render of the window {render * 1e3:.0f} ms")


def charts() -> None:
    chart_cost("livox_mid70", "petal_height", [3.0 + 0.2 * k for k in range(9)])
    chart_cost("livox_mid70_risley", "prism_rpm_a", [4000.0 + 50 * k for k in range(9)])


if __name__ == "__main__":
    main()
    charts()
