"""The general track stream: any Livox head as a two-frequency series (:mod:`~livox_viz.config.track_params`).

The series is evaluated by the Risley stream's kernel
(:class:`~livox_viz.patterns.risley.RisleyPattern`: sample k is the series at
t = k / rate, laser k mod K, block-start phasors computed from k directly, so
nothing drifts however long it runs). A ``"spin"`` track then adds the
azimuth's turn, degrees(A(t)) with A's phase also taken from k directly, and
every panorama-plane point has its azimuth wrapped to [-180, 180).
"""

from __future__ import annotations

import math

import numpy as np

from livox_viz.config.sensor import SensorConfig
from livox_viz.config.track_params import TrackParams
from livox_viz.core.errors import ConfigError
from livox_viz.patterns.risley import RisleyPattern
from livox_viz.patterns.stream import PatternChunk


class TrackPattern(RisleyPattern):
    """The endless, deterministic point stream of a ``"track"`` configuration.

    Parameters
    ----------
    config : SensorConfig
        With ``pattern_model == "track"``.
    seed : int
        Ignored (the track is deterministic); kept for a common interface.
    """

    def __init__(self, config: SensorConfig, seed: int = 0) -> None:
        if config.track is None or config.pattern_model != "track":
            raise ConfigError("the track pattern needs LivoxVizTrack parameters (e.g. preset livox_horizon)")
        super().__init__(config, seed)
        self._spin_cycles_per_sample = config.track.spin_hz / config.point_rate
        self._spin_phase_deg = math.degrees(config.track.phase_rad[0]) if config.track.form == "spin" else 0.0
        self._panorama = config.pattern_plane == "panorama"
        self._ramp = np.zeros(0)

    def points(self, start: int, count: int) -> PatternChunk:
        """Points ``start .. start+count-1`` (any range: the track is a function of k alone)."""
        chunk = super().points(start, count)
        if not self._panorama:
            return chunk
        x = chunk.xy_deg[:, 0]
        if self._spin_cycles_per_sample:
            # The turn of sample k is (k c) mod 1 from k itself, not the chunk's first turn plus i c: the same
            # number however the stream is cut (a chunk of seven frames or seven chunks of one; k c has one
            # rounding, 2e-12 of a turn at ten minutes).
            if self._ramp.size < count:
                self._ramp = np.arange(count, dtype=np.float64)
            turns = self._ramp[:count] + float(start)
            turns *= self._spin_cycles_per_sample
            np.mod(turns, 1.0, out=turns)
            turns *= 360.0
            x += turns
            x += self._spin_phase_deg
        wrap_azimuth(x)
        return chunk


def wrap_azimuth(x_deg: np.ndarray) -> np.ndarray:
    """Wrap azimuths into [-180, 180) in place; returns the array."""
    x_deg += 180.0
    np.mod(x_deg, 360.0, out=x_deg)
    x_deg -= 180.0
    return x_deg


def track_xy(params: TrackParams, t: np.ndarray, laser: np.ndarray | None = None,
             panorama: bool | None = None) -> np.ndarray:
    """The track evaluated directly at times ``t`` (the reference the stream is tested against).

    Parameters
    ----------
    params : TrackParams
    t : (n,) float64
        Seconds.
    laser : (n,) int, optional
        Laser of each sample; default laser 0.
    panorama : bool, optional
        Wrap the azimuth (default: for a spin track).

    Returns
    -------
    xy_deg : (n, 2) float64
    """
    t = np.asarray(t, dtype=np.float64)
    laser = np.zeros(t.shape, dtype=np.int64) if laser is None else np.asarray(laser)
    phase = 2.0 * np.pi * np.outer(t, params.term_hz) + params.term_phase[None, :]
    w = np.sum(params.coefficients[laser] * np.exp(1j * phase), axis=1)
    xy = np.column_stack([w.real, w.imag])
    if params.form == "spin":
        xy[:, 0] += np.degrees(2.0 * np.pi * params.base_hz[0] * t + params.phase_rad[0])
    if params.form == "spin" if panorama is None else panorama:
        wrap_azimuth(xy[:, 0])
    return xy
