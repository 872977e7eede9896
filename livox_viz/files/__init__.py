"""Stage 6b, files and bags: frames written to disk, streamed, never half-written.

Takes frames of points (scanned or received) and gives point-cloud files (PLY, PCD,
LAS, NPZ, CSV in :mod:`~livox_viz.files.export`, column-streamed ``.npz`` in
:mod:`~livox_viz.files.npzstream`; Livox's LVX2 and LVX 1.1 in
:mod:`~livox_viz.files.lvx_write`) and ROS 2 bags with the IMU and ground truth
(:mod:`~livox_viz.files.rosbag`); it reads Livox recordings (LVX2, LVX 1.1, the
drivers' ROS 1 and ROS 2 bags) into one :class:`~livox_viz.files.livox_recording.LivoxRecording`.
"""

from livox_viz.files.livox_reference import register as _register_recordings

_register_recordings()
