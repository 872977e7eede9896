"""Which stream a configuration scans: the one place that knows every pattern model."""

from __future__ import annotations

from livox_viz.config.sensor import SensorConfig
from livox_viz.patterns.risley import RisleyPattern
from livox_viz.patterns.rosette import ScanPattern
from livox_viz.patterns.stream import PatternStream
from livox_viz.patterns.track import TrackPattern


def make_pattern(config: SensorConfig, seed: int = 0) -> PatternStream:
    """The point stream of ``config``'s pattern model: :class:`ScanPattern`, :class:`RisleyPattern` or
    :class:`TrackPattern`.

    Both offer ``take``, ``take_until``, ``next_frame``, ``skip``, ``points``,
    ``position`` and ``time``, and make :class:`~livox_viz.patterns.stream.PatternChunk` objects.
    """
    if config.pattern_model == "track":
        return TrackPattern(config, seed)
    if config.pattern_model == "risley":
        return RisleyPattern(config, seed)
    return ScanPattern(config, seed)
