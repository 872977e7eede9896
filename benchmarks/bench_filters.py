"""The scene view's range and reflectivity filter (View > Filters) at a million points.

Printed, each the best of several runs:

1. The filter's own work on a full ring of 1 000 000 points (the unlimited window): the mask over the ring's
   arrays and the slots it keeps, for the every-point drawing and the thinned one (1 in 4), and the vertex
   cells VTK is handed.
2. The scene view's refresh (what a tick adds to its work) with and without the filter, off-screen, the window
   holding a million points of the default preset in the urban scene, as bench_window.py fills it.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import best_of
from livox_viz.widgets.filters import CloudFilter, filtered_slots
from livox_viz.widgets.ring import PointRing
from livox_viz.widgets.views import drawn_slots

POINTS = 1_000_000
FILTER = CloudFilter(range_min_m=1.0, range_max_m=20.0, reflectivity_min=10)


def full_ring(rng: np.random.Generator) -> PointRing:
    ring = PointRing(POINTS, sensor_frame=True)
    local = rng.normal(0.0, 15.0, (POINTS, 3)).astype(np.float32)
    ring.write(local, np.zeros(POINTS, np.float32), np.linspace(0.0, 10.0, POINTS), np.arange(POINTS),
               reflectivity=rng.integers(0, 256, POINTS).astype(np.uint8), sensor_xyz=local)
    return ring


def filter_alone() -> None:
    import pyvista as pv

    ring = full_ring(np.random.default_rng(0))
    for stride, drawing in ((1, "every point"), (4, "thinned 1 in 4")):
        slots = drawn_slots(ring, stride)
        kept, hidden = filtered_slots(ring, slots, FILTER)
        mask = best_of(lambda s=slots: filtered_slots(ring, s, FILTER), 7)
        cells = best_of(lambda k=kept: pv.CellArray.from_arrays(ring.cell_offsets()[: k.size + 1], k), 7)
        print(f"filter, {drawing}: {1e3 * mask:6.1f} ms mask and slots, {1e3 * cells:5.1f} ms cells "
              f"({kept.size:,} drawn, {hidden:,} of {ring.count:,} hidden)")


def in_the_view() -> None:
    import tempfile

    import bench_window

    from livox_viz.scene.raycast import EmbreeCaster
    from livox_viz.scene.scenes import open_scene

    bench_window.CASTER = EmbreeCaster(open_scene("urban").mesh)
    bench_window.SCREENSHOTS = Path(tempfile.mkdtemp()) / "shots"
    session, app = bench_window.filled()
    view = app.scene_view
    render = app.plotters["scene"].ren_win.Render

    def refresh_changed() -> None:
        # A tick changes the ring: the filter's cells are made again (its key holds the scan time).
        session.scan_time += 1e-9
        view.update()

    try:
        for drawing in ("points", "auto"):
            session.display.drawing = drawing
            # Ideal returns carry reflectivity 0: a range filter alone, which hides some of them.
            for name, cloud_filter in (("no filter", CloudFilter()), ("filter", CloudFilter(1.0, 40.0))):
                view.cloud_filter = cloud_filter
                refresh_changed()
                update = best_of(refresh_changed, 5)
                drawn = best_of(lambda: (refresh_changed(), render()), 3) - update
                print(f"scene view, {session.scene_ring.count:,} points, drawing {drawing}, {name}: update "
                      f"{1e3 * update:6.1f} ms, render {1e3 * drawn:5.0f} ms "
                      f"({view.filter_line() or 'every point drawn'})")
    finally:
        app.close()


if __name__ == "__main__":
    start = time.perf_counter()
    filter_alone()
    if "--quick" not in sys.argv:
        in_the_view()
    print(f"({time.perf_counter() - start:.0f} s)")
