"""The bottom of the model: what every stage uses and nothing else imports below.

Takes nothing from the rest of livox_viz and gives the one error family for bad
input (:mod:`~livox_viz.core.errors`), the documented work budget, the progress
line, files written through a temporary and a rename (:mod:`~livox_viz.core.atomic`),
the hardened JSON reader, and the geometry every frame of reference is built
from: rotation matrices, Euler angles and quaternions, the NED/FRD to ENU/FLU
conversions (:mod:`~livox_viz.core.rotations`) and rigid poses
(:mod:`~livox_viz.core.poses`).
"""
