"""Comparing a configuration's pattern with a reference: coverage, density, track residual.

Each pattern's coverage counts the cells of its own field of view (a cone, an
outline, a band); both densities run over the union of the two profiles.
Memory is bounded: at most :data:`COMPARE_MAX_SECONDS` of each are compared,
and our side is checked against the work budget first.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from livox_viz.config.sensor import SERIES_MODELS, SensorConfig
from livox_viz.core.errors import LivoxVizError
from livox_viz.core.workload import check_points
from livox_viz.fitting.reference import ReferencePattern
from livox_viz.patterns.factory import make_pattern
from livox_viz.patterns.metrics import radial_density, window_coverage
from livox_viz.patterns.stream import points_before

COMPARE_TIMES = (0.05, 0.1, 0.2, 0.3, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0)
#: A window may end this share of its firings past a table's last row: a recording's last firings may have
#: returned nothing (a 0.1 s frame whose last row is a no-return is still compared over 0.1 s).
TAIL_SHARE = 0.01
#: The longest span compared, seconds (a longer reference is compared over its first minute).
COMPARE_MAX_SECONDS = 60.0


@dataclass(frozen=True)
class Comparison:
    """Ours against a reference: coverage against integration time and density along the FOV's profile."""

    seconds: np.ndarray
    coverage_ours: np.ndarray
    coverage_reference: np.ndarray
    density_edges_deg: np.ndarray
    density_ours: np.ndarray
    density_reference: np.ndarray
    #: (rms, p95, max) degrees between rays sample for sample, when ours is a deterministic track at the
    #: reference's rate.
    track_residual: tuple[float, float, float] | None = None
    #: Seconds of each that were compared.
    span_seconds: float = 0.0
    #: What the density runs along ("angle off the boresight, deg" or "elevation, deg").
    profile_label: str = "angle off the boresight, deg"
    #: Why there is no track residual, in words ("" when there is one).
    no_residual_because: str = ""


def compare(config: SensorConfig, reference: ReferencePattern, seed: int = 0,
            seconds: tuple[float, ...] = COMPARE_TIMES, bins: int = 30) -> Comparison:
    """Coverage (each pattern in its own FOV) and density (points per sr per second) of both."""
    if config.pattern_plane != reference.plane:
        raise LivoxVizError(f"{reference.name} is a {reference.plane} pattern and the configuration a "
                            f"{config.pattern_plane} one; allowed: two patterns in the same plane")
    duration = min(reference.seconds, COMPARE_MAX_SECONDS)
    # The rows of the compared span (a table with gaps has fewer rows than firings).
    rows = int(np.searchsorted(reference.slots, points_before(duration, reference.rate)))
    # The firings the rows span, from firing 0 (a recording's no-returns are gaps, not rows).
    reach = int(reference.slots[rows - 1]) + 1 if rows else 0
    tail = 1.0 if reference.consecutive else 1.0 + TAIL_SHARE
    usable = tuple(t for t in seconds if points_before(t, reference.rate) <= reach * tail
                   and points_before(t, config.point_rate) <= points_before(duration, config.point_rate) * tail)
    if not usable or rows < 2:
        raise LivoxVizError(f"the reference holds {reference.seconds:.3g} s; allowed: at least {min(seconds):g} s")
    count = points_before(duration, config.point_rate)
    check_points(count, f"comparing {duration:g} s of a {config.point_rate:,} pts/s pattern")
    longest = make_pattern(config, seed=seed).take(max(count, points_before(max(usable), config.point_rate))).xy_deg
    ours = longest[:count]
    reference_xy = reference.xy_deg[:rows]
    ours_fov, reference_fov = config.field_of_view, reference.field_of_view
    ours_cov = window_coverage(longest, config.point_rate, usable, ours_fov)
    ref_cov = window_coverage(reference_xy, reference.rate, usable, reference_fov,
                              slots=None if reference.consecutive else reference.slots[:rows])
    low = min(ours_fov.profile_range[0], reference_fov.profile_range[0])
    high = max(ours_fov.profile_range[1], reference_fov.profile_range[1])
    edges, ours_density = radial_density(ours, ours_fov, bins, (low, high))
    _, ref_density = radial_density(reference_xy, reference_fov, bins, (low, high))
    residual, because = None, ""
    if config.pattern_model not in SERIES_MODELS:
        because = (f"ours is RflySim's rosette ({config.pattern_model} model), whose seeded petals follow no track "
                   "sample for sample")
    elif config.point_rate != reference.rate:
        because = (f"the rates differ (ours {config.point_rate:,} pts/s, the reference's {reference.rate:,.6g} "
                   "rows/s): sample k is not the same moment in both")
    else:
        from livox_viz.fitting.risley_fit import track_residual

        # Each row against our sample of the same firing (a table with gaps skips ours where it has no row).
        residual = track_residual(ours[reference.slots[:rows]], reference_xy, config.pattern_plane)
    return Comparison(np.array(usable), ours_cov, ref_cov, edges, ours_density / duration,
                      ref_density / duration, residual, duration, ours_fov.profile_label, no_residual_because=because)
