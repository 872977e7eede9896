"""Stage 2, the pattern: a configuration becomes an endless stream of scan angles.

Takes a :class:`~livox_viz.config.sensor.SensorConfig` and gives
:class:`~livox_viz.patterns.stream.PatternChunk` runs of pattern angles (degrees,
x right, y up) with their firing times: RflySim's petal rosette
(:mod:`~livox_viz.patterns.rosette`) or the real sensors' prism track
(:mod:`~livox_viz.patterns.risley`), picked by :func:`~livox_viz.patterns.factory.make_pattern`;
and the measures of a pattern, coverage and radial density (:mod:`~livox_viz.patterns.metrics`).
"""
