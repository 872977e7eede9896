"""The sensor's mount on the vehicle (``SensorPosXYZ``, ``SensorAngEuler`` or, in RflySim v3's form with
``EularOrQuat`` > 0.5, ``SensorAngQuat``) and its pose in the world.

The mount is a :class:`~livox_viz.core.poses.Pose` in the vehicle body FRD frame;
the sensor's world pose is the vehicle's pose composed with it (scan-model.md section 5).
"""

from __future__ import annotations

import numpy as np

from livox_viz.config.sensor import SensorConfig
from livox_viz.core.poses import Pose, pose_from_quaternion


def sensor_mount(config: SensorConfig) -> Pose:
    """The sensor's pose in the vehicle body frame: ``SensorPosXYZ`` (m), and ``SensorAngEuler`` (rad) or the
    quaternion ``SensorAngQuat`` ([w, x, y, z], normalised) where ``EularOrQuat`` > 0.5 chooses it."""
    quaternion = config.mount_quaternion
    if quaternion is not None:
        return pose_from_quaternion(np.array(config.sensor_pos_xyz), np.array(quaternion))
    return Pose(config.sensor_pos_xyz, *config.sensor_ang_euler)


def sensor_world_pose(config: SensorConfig, vehicle: Pose) -> Pose:
    """The sensor's pose in the world, the vehicle pose composed with the mount."""
    return vehicle.compose(sensor_mount(config))
