"""Stage 3, the vehicle's motion: where the sensor is at every point's own time.

Takes a TUM file (:mod:`~livox_viz.motion.tum`) or a built-in flight
(:mod:`~livox_viz.motion.flights`) and gives a :class:`~livox_viz.motion.trajectory.Trajectory`
(vehicle poses in world NED, interpolated to any time) and what an IMU on the vehicle
reads along it (:mod:`~livox_viz.motion.imu`).
"""
