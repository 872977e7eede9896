"""Stage 6b, files and bags: frames written to disk, streamed, never half-written.

Takes frames of points (scanned or received) and gives point-cloud files (PLY, PCD,
LAS, NPZ, CSV in :mod:`~livox_viz.files.export`, column-streamed ``.npz`` in
:mod:`~livox_viz.files.npzstream`) and ROS 2 bags with the IMU and ground truth
(:mod:`~livox_viz.files.rosbag`).
"""
