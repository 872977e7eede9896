"""Stage 1, the sensor: RflySim's TypeID-6 JSON object as a validated, frozen value.

Takes a JSON file or a preset name and gives a :class:`~livox_viz.config.sensor.SensorConfig`
(W, H, F, FOV, ``otherParams``, the mount, the pattern model and its parameters), the
Risley and general track parameters it may carry (:mod:`~livox_viz.config.risley_params`,
:mod:`~livox_viz.config.track_params`), the sensor's own field of view
(:mod:`~livox_viz.config.fov`), the
sensor's mount on the vehicle (:mod:`~livox_viz.config.mount`) and the shipped and user
presets (:mod:`~livox_viz.config.presets`).
"""
