"""Stage 5, the scan: pattern angles become rays, rays become returns, returns become int16 points.

Takes pattern chunks, the sensor's pose (fixed or along a trajectory) and a ray
caster, and gives :class:`~livox_viz.casting.scan.ScanFrame` objects: the returns of
each ray (:mod:`~livox_viz.casting.directions` turns angles into FRD rays), their
int16 encoding (:mod:`~livox_viz.casting.codec`) and the decoded points a RflySim
client sees. :mod:`~livox_viz.casting.point_frame` says what any frame of points
offers to the later stages.
"""
