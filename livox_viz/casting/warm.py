"""Warming the compiled loops: compile them (or load them from numba's cache) before they are needed.

numba compiles a loop on its first call: the return model's loops take one to
two minutes the first time on 2 cores (then seconds, from the cache beside
each module), the caster's a few seconds, the Risley product one. A program
that must not stall (the window) runs :func:`warm` for the stages it will need
ahead of time, in a child process for a first compile (``python -m
livox_viz.casting.warm STAGE ...``: it fills the cache on another core without
holding this process's GIL) and then in a thread of its own, which loads the
cached loops.

Each stage runs a little real work through the loops it names, so the
signatures compiled are the ones a scan uses:

``ideal``
    the ray caster and the ideal return (a fixed sensor).
``risley``
    the Risley and track streams' block product.
``datasheet``
    the datasheet return model (beam footprint, echoes, detection), for a
    boresight head and for a 360-degree one.
``motion``
    a moving sensor's per-ray poses, under both return models.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Iterable

from livox_viz.config.sensor import SERIES_MODELS, SensorConfig

#: The stages, in the order a program needs them.
STAGES: tuple[str, ...] = ("ideal", "risley", "datasheet", "motion")


def pattern_stages(config: SensorConfig) -> set[str]:
    """The stages ``config``'s pattern alone uses (a reference overlay plays only the pattern): ``{"risley"}`` for
    a series track, none for the rosette.

    Parameters
    ----------
    config : SensorConfig
    """
    return {"risley"} if config.pattern_model in SERIES_MODELS else set()


def stages_for(config: SensorConfig, moving: bool = False) -> set[str]:
    """The stages a scan of ``config`` uses (``moving``: with a trajectory).

    Parameters
    ----------
    config : SensorConfig
    moving : bool
    """
    needed = {"ideal", *pattern_stages(config)}
    if config.returns_model == "datasheet":
        needed.add("datasheet")
    if moving:
        needed.add("motion")
    return needed


def _cast(preset: str, returns: str, frames: int = 2, moving: bool = False, small: bool = False) -> None:
    from livox_viz.casting.scan import MountedCaster
    from livox_viz.config.presets import load_preset
    from livox_viz.motion.flights import builtin_trajectory
    from livox_viz.patterns.factory import make_pattern
    from livox_viz.scene.raycast import EmbreeCaster
    from livox_viz.scene.scenes import open_scene

    config = load_preset(preset).with_returns_model(returns)
    if small:  # the ideal return's loops meet every scene alike: a box in front is enough, and quick to build
        import trimesh

        from livox_viz.core.poses import Pose

        mesh, pose = trimesh.creation.box((4.0, 40.0, 40.0)).apply_translation((12.0, 0.0, 0.0)), Pose()
    else:
        scene = open_scene("urban")
        mesh, pose = scene.mesh, scene.vehicle_pose
    trajectory = builtin_trajectory("line", 5.0, pose, 1.0) if moving else None
    caster = MountedCaster(config, EmbreeCaster(mesh), pose, trajectory, 0)
    pattern = make_pattern(config, 0)
    for _ in range(frames):
        caster.cast(pattern.take(config.points_per_frame))


def warm(stage: str) -> float:
    """Compile (or load from the cache) the loops of ``stage``; the seconds it took.

    Raises
    ------
    ValueError
        For a stage not in :data:`STAGES`.
    """
    start = time.perf_counter()
    if stage == "ideal":
        _cast("livox_mid70", "ideal", small=True)
    elif stage == "risley":
        from livox_viz.config.presets import load_preset
        from livox_viz.patterns.factory import make_pattern

        make_pattern(load_preset("livox_mid70_risley")).take(12_345)
    elif stage == "datasheet":
        _cast("livox_mid70", "datasheet")
        _cast("livox_mid360", "datasheet")
    elif stage == "motion":
        _cast("livox_mid70", "ideal", moving=True)
        _cast("livox_mid70", "datasheet", moving=True)
    else:
        raise ValueError(f"stage {stage!r}; allowed: {', '.join(STAGES)}")
    return time.perf_counter() - start


def main(arguments: Iterable[str]) -> int:
    """Warm the stages named in turn, printing ``ready STAGE SECONDS`` after each (read by the window).

    ``--background`` first lowers this process's priority (where the platform lets a process do so itself), so
    that a window it works for keeps its frames on a machine of few cores.
    """
    stages = [a for a in arguments if a != "--background"]
    if "--background" in arguments and hasattr(os, "nice"):
        os.nice(10)
    for stage in stages:
        if stage not in STAGES:
            print(f"error: stage {stage!r}; allowed: {', '.join(STAGES)}", file=sys.stderr)
            return 2
    for stage in stages:
        seconds = warm(stage)
        print(f"ready {stage} {seconds:.2f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
