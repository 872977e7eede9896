"""Live charts beside the views: FOV coverage against integration time, and radial density, ours and the reference's.

Both curves of ours are recomputed whenever the configuration changes (the
session tells us), from the pattern's first seconds (at most a million points,
so a slider change redraws them in well under 100 ms); the reference's when
the overlay's source changes, on a worker thread: a reference at another
sensor's rate is a million points of a longer series (100-400 ms), which the
key that chose it would otherwise wait for. Its curves appear at the first
refresh after they are ready (:meth:`CurveCharts.finish` waits for them). They
are pyvista's own charts (VTK context 2D), drawn in the same window as the views.
"""

from __future__ import annotations

import time
from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np
import pyvista as pv

from livox_viz.patterns.metrics import (
    CURVE_POINTS,
    CURVE_SECONDS,
    PatternCurves,
    config_curves,
    received_curves,
    stream_curves,
)
from livox_viz.patterns.stream import points_before

from .overlay import PresetSource, TableSource
from .session import Session

OURS_COLOUR = "#e0a526"
REFERENCE_COLOUR = "#8c8c8c"  # grey, as the pattern view draws the reference
_NOT_SHOWN = object()
#: What a pending computation of "ours" is for when it is the live stream's, not a configuration's.
_STREAM = object()
#: Seconds between two computations of a live stream's curves (from the points the pattern view holds).
STREAM_CURVES_EVERY_S = 1.0


def reference_curves(source: TableSource | PresetSource) -> PatternCurves:
    """The reference's curves over its first seconds (a table from its first row)."""
    if isinstance(source, PresetSource):
        return config_curves(source.config, source.seed)
    table = source.table
    # The rows fired in the chart's span (a recording's no-returns are gaps: its rows at their own firings).
    count = min(int(np.searchsorted(table.slots, points_before(max(CURVE_SECONDS), source.rate))), CURVE_POINTS)
    return stream_curves(table.xy_deg[:count], source.rate, source.fov,
                         slots=None if table.consecutive else table.slots[:count])


def curve_label(name: str, curves: PatternCurves, span: float | None = None) -> str:
    """A coverage curve's legend entry; it says where the curve stops short of the chart's 4 s: where a table or
    recording of ``span`` seconds ends (a 0.1 s frame), or where the point budget cut it (a 1 M pts/s pattern's
    first 2 M points are 2 s)."""
    end = float(curves.seconds[-1]) if len(curves.seconds) else 0.0
    if end >= max(CURVE_SECONDS) - 1e-9:
        return name
    if span is not None and span < max(CURVE_SECONDS):
        return f"{name} (its {span:.3g} s)"
    return f"{name} (to {end:g} s: {CURVE_POINTS // 1_000_000} M points)"


def _chart(loc: tuple[float, float], x_label: str, y_label: str) -> pv.Chart2D:
    chart = pv.Chart2D(size=(0.96, 0.47), loc=loc, x_label=x_label, y_label=y_label)
    chart.background_color = (0.93, 0.94, 0.96, 1.0)
    chart.legend_visible = True
    return chart


class CurveCharts:
    """The two charts in one subplot of the window.

    Parameters
    ----------
    plotter : pyvista.Plotter
    subplot : tuple of int
    session : Session
    """

    def __init__(self, plotter: pv.Plotter, subplot: tuple[int, int], session: Session) -> None:
        self.session = session
        plotter.subplot(*subplot)
        plotter.set_background("#10141c")
        self.coverage = _chart((0.02, 0.515), "integration time, s (log)", "FOV coverage, %")
        self.coverage.x_axis.log_scale = True
        self.coverage.x_axis.range = [min(CURVE_SECONDS), max(CURVE_SECONDS)]
        self.coverage.y_axis.range = [0.0, 100.0]
        self.density = _chart((0.02, 0.015), session.config.field_of_view.profile_label, "M points / sr / s (log)")
        self.density.y_axis.log_scale = True
        placeholder = ([0.05, 4.0], [0.0, 0.0])
        self.ours_coverage = self.coverage.line(*placeholder, color=OURS_COLOUR, width=2.5, label="ours")
        self.reference_coverage = self.coverage.line(*placeholder, color=REFERENCE_COLOUR, width=2.5,
                                                     label="reference")
        self.ours_density = self.density.line([0.0, 1.0], [0.0, 0.0], color=OURS_COLOUR, width=2.5, label="ours")
        self.reference_density = self.density.line([0.0, 1.0], [0.0, 0.0], color=REFERENCE_COLOUR, width=2.5,
                                                   label="reference")
        plotter.add_chart(self.coverage, self.density)
        self.ours: PatternCurves | None = None
        self.reference: PatternCurves | None = None
        #: Whether the charts changed since they were last drawn (the window renders them only then).
        self.dirty = True
        self._reference_source: object = _NOT_SHOWN
        self._worker: ThreadPoolExecutor | None = None
        self._pending: tuple[object, Future[PatternCurves]] | None = None
        self._ours_pending: tuple[object, Future[PatternCurves]] | None = None
        #: The live view's stream: when its curves were last asked for (monotonic s), and of which points.
        self._stream_asked = -float("inf")
        self._stream_points: tuple[int, float] | None = None
        self._stream_span = 0.0  # seconds between the first and the last of the points asked for
        session.subscribe(self._on_change)
        self.refresh_ours()
        self.finish()  # the first picture has them

    def _on_change(self, what: str) -> None:
        if what == "config" and self.session.source is None:
            self.refresh_ours()

    def _submit(self, work, *args) -> Future:
        if self._worker is None:
            self._worker = ThreadPoolExecutor(1, thread_name_prefix="livox-viz-curves")
        return self._worker.submit(work, *args)

    def refresh_ours(self) -> None:
        """Recompute our two curves from the session's configuration on the worker (up to 2 M points of pattern:
        80 ms for the HAP, which a parameter change would otherwise wait for); drawn when ready."""
        config = self.session.config
        self.density.x_label = config.field_of_view.profile_label
        self._ours_pending = (config, self._submit(config_curves, config, self.session.seed))

    def _show_ours(self, curves: PatternCurves, name: str = "ours", span: float | None = None) -> None:
        shown = curves.seconds.size > 0
        self.ours = curves if shown else None
        self.ours_coverage.visible = shown
        self.ours_density.visible = shown
        if shown:
            self.ours_coverage.update(curves.seconds, 100.0 * curves.coverage)
            self.ours_density.update(curves.density_alpha_deg, curves.density / 1e6)
            self.ours_coverage.label = curve_label(name, curves, span)
            self.ours_density.label = name
        self._fit_density_axes()
        self.dirty = True

    def _follow_stream(self) -> None:
        """The live view: "ours" is the stream's own curves, from the points the pattern view holds (what
        arrived in the integration window), asked for each :data:`STREAM_CURVES_EVERY_S` while new points come;
        the model's curves would show a scan that is not the one arriving. None until the first points."""
        if self._stream_points is None:  # the model's curves, drawn before the window listened, go
            self._stream_points = (0, 0.0)
            self._ours_pending = None
            self._show_ours(PatternCurves(np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0)))
        ring = self.session.pattern_ring
        now = time.monotonic()
        if self._ours_pending is not None or now - self._stream_asked < STREAM_CURVES_EVERY_S or ring.count < 2:
            return
        pieces = ring.live_pieces()
        newest = float(ring.times[pieces[-1].stop - 1])
        if self._stream_points == (ring.count, newest):
            return  # nothing new arrived (paused, or the sender stopped): the curves stand
        self._stream_points = (ring.count, newest)
        self._stream_asked = now
        xy = np.concatenate([ring.positions[piece, :2] for piece in pieces]).astype(np.float64)
        times = np.concatenate([ring.times[piece] for piece in pieces]).astype(np.float64)
        self._stream_span = float(times.max() - times.min())
        config = self.session.config
        self._ours_pending = (_STREAM, self._submit(received_curves, xy, times, float(config.point_rate),
                                                    config.field_of_view))

    def update(self) -> None:
        """Follow the overlay: the reference's curves when its source changed (computed on the worker and drawn
        once ready), hidden without one; in the live view, the stream's curves as they come."""
        if self.session.source is not None:
            self._follow_stream()
        if self._ours_pending is not None and self._ours_pending[1].done():
            config, future = self._ours_pending
            self._ours_pending = None
            if config is _STREAM and self.session.source is not None:
                self._show_ours(future.result(), "stream", self._stream_span)
            elif config is self.session.config and self.session.source is None:
                self._show_ours(future.result())  # a newer change has its own on the way
        source = self.session.overlay.source
        if source is not self._reference_source:
            self._reference_source = source
            self.reference = None
            self._pending = None
            if source is not None:
                self._pending = (source, self._submit(reference_curves, source))
            self._show_reference()
        if self._pending is not None and self._pending[1].done():
            source, future = self._pending
            self._pending = None
            if source is self._reference_source:
                self.reference = future.result()
                self._show_reference()

    def finish(self) -> None:
        """Wait for the curves being computed (ours and the reference's), and draw them."""
        for pending in (self._ours_pending, self._pending):
            if pending is not None:
                pending[1].result()
        self.update()

    def close(self) -> None:
        """Stop the worker (a computation under way is left to end on its own)."""
        if self._worker is not None:
            self._worker.shutdown(wait=False, cancel_futures=True)
            self._worker = None

    def _show_reference(self) -> None:
        shown = self.reference is not None
        self.reference_coverage.visible = shown
        self.reference_density.visible = shown
        if shown:
            self.reference_coverage.update(self.reference.seconds, 100.0 * self.reference.coverage)
            self.reference_density.update(self.reference.density_alpha_deg, self.reference.density / 1e6)
            source = self._reference_source
            span = source.table.seconds if isinstance(source, TableSource) else None
            self.reference_coverage.label = curve_label("reference", self.reference, span)
        self._fit_density_axes()
        self.dirty = True

    def _fit_density_axes(self) -> None:
        curves = [c for c in (self.ours, self.reference) if c is not None and c.density.size]
        if not curves:
            return
        top = max(float(np.max(c.density)) for c in curves) / 1e6
        positive = [float(np.min(c.density[c.density > 0])) for c in curves if np.any(c.density > 0)]
        bottom = min(positive) / 1e6 if positive else 1e-3
        left = min(min(float(c.density_alpha_deg[0]) for c in curves), 0.0)
        right = max(float(c.density_alpha_deg[-1]) for c in curves)
        self.density.x_axis.range = [left - 0.04 * abs(left), right + 0.04 * abs(right)]
        # Once VTK has drawn a log axis it keeps its range in log10 units, and SetRange (pyvista's range) is
        # read in those units: 0.02-9.8 became 10^0.02-10^9.8. The unscaled range is always in data units.
        y_axis = self.density.y_axis
        y_axis.behavior = "fixed"
        y_axis.SetUnscaledRange(bottom / 1.5, max(top * 1.5, bottom * 10))
