"""Pattern angles to unit rays in the sensor frame (scan-model.md section 5, and the panorama plane).

The mapping lives in :mod:`livox_viz.patterns.planes` (fitting measures residuals
as angles between rays with it too); this module is the casting path's name for it.
A sample (x, y) in degrees of the boresight plane is a direction
``alpha = hypot(x, y)`` off the boresight, rolled by ``beta = atan2(y, x)`` about it;
in the panorama plane x is the azimuth (positive right) and y the elevation. The
sensor frame is FRD: x forward along the boresight, y right, z down.
"""

from __future__ import annotations

from livox_viz.patterns.planes import directions_from_xy, xy_from_directions

__all__ = ["directions_from_xy", "xy_from_directions"]
