"""Stage 2, the pattern: a configuration becomes an endless stream of scan angles.

Takes a :class:`~livox_viz.config.sensor.SensorConfig` and gives
:class:`~livox_viz.patterns.stream.PatternChunk` runs of pattern angles (degrees,
x right, y up; or azimuth and elevation for a 360-degree head) with their firing times:
RflySim's petal rosette (:mod:`~livox_viz.patterns.rosette`), the real sensors' prism track
(:mod:`~livox_viz.patterns.risley`) or any head's track (:mod:`~livox_viz.patterns.track`),
picked by :func:`~livox_viz.patterns.factory.make_pattern`; the two pattern planes and their
rays (:mod:`~livox_viz.patterns.planes`); and the measures of a pattern, coverage and density
in its field of view (:mod:`~livox_viz.patterns.metrics`).
"""
