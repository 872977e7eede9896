"""Comparing a configuration's pattern with a reference: coverage, radial density, track residual.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from livox_viz.config.sensor import SensorConfig
from livox_viz.core.errors import LivoxVizError
from livox_viz.fitting.reference import ReferencePattern
from livox_viz.patterns.factory import make_pattern
from livox_viz.patterns.metrics import window_coverage
from livox_viz.patterns.stream import points_before

COMPARE_TIMES = (0.05, 0.1, 0.2, 0.3, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0)


@dataclass(frozen=True)
class Comparison:
    """Ours against a reference: coverage against integration time and radial density."""

    seconds: np.ndarray
    coverage_ours: np.ndarray
    coverage_reference: np.ndarray
    density_edges_deg: np.ndarray
    density_ours: np.ndarray
    density_reference: np.ndarray
    #: (rms, p95, max) degrees sample for sample, when ours is a deterministic track at the reference's rate.
    track_residual: tuple[float, float, float] | None = None


def compare(config: SensorConfig, reference: ReferencePattern, seed: int = 0,
            seconds: tuple[float, ...] = COMPARE_TIMES, bins: int = 30) -> Comparison:
    """Coverage (each pattern in its own FOV) and radial density (points per sr per second) of both."""
    from livox_viz.patterns.metrics import radial_density

    usable = tuple(t for t in seconds if t * reference.rate <= len(reference.t)
                   and t * config.point_rate <= 50_000_000)
    if not usable:
        raise LivoxVizError(f"the reference holds {reference.seconds:.3g} s; allowed: at least {min(seconds):g} s")
    duration = reference.seconds
    ours = make_pattern(config, seed=seed).take(points_before(duration, config.point_rate)).xy_deg
    ref_radius = float(reference.alpha_deg.max())
    ours_cov = window_coverage(ours, config.point_rate, usable, config.half_fov_deg)
    ref_cov = window_coverage(reference.xy_deg, reference.rate, usable, ref_radius)
    radius = max(config.half_fov_deg, ref_radius)
    edges, ours_density = radial_density(ours, radius, bins)
    _, ref_density = radial_density(reference.xy_deg, radius, bins)
    residual = None
    if config.pattern_model == "risley" and config.point_rate == reference.rate and len(ours) == len(reference.t):
        from livox_viz.fitting.risley_fit import track_residual

        residual = track_residual(ours, reference.xy_deg)
    return Comparison(np.array(usable), ours_cov, ref_cov, edges, ours_density / duration,
                      ref_density / duration, residual)
