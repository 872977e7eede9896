"""A batch spec: a grid of scans (sensors x scenes x trajectories x seeds x return models x outputs) as jobs.

A spec is a TOML or JSON file::

    seconds = 1.0                       # every job's scan time
    [grid]
    sensors = ["livox_mid70", "my_sensor.json"]
    scenes = ["urban", "warehouse.glb"]
    trajectories = ["none", "line"]
    seeds = [0, 1]
    returns = ["ideal", "datasheet"]
    outputs = ["npz", "las+rosbag"]

Every combination of the grid's lists is one job, a normal ``livox-viz scan``
(:func:`scan_argv`) with a folder of its own. A job is named by what it scans
and a hash of all its parameters (:attr:`Job.name`), so the same spec makes the
same jobs in the same folders, and a rerun finds the ones already done. Everything
is checked before any job starts (:func:`read_spec`): unknown keys, values, the
number of jobs, files that do not exist, each job's points; each message names
the field and what is allowed. A file that exists but does not load (a broken
mesh) is the job's own failure, reported with its message.
"""

from __future__ import annotations

import functools
import hashlib
import itertools
import json
import math
import re
import tomllib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, overload

from livox_viz.config.presets import list_presets
from livox_viz.config.returns_params import RETURN_MODELS
from livox_viz.config.sensor import load_config
from livox_viz.core.errors import LivoxVizError
from livox_viz.core.jsonfile import read_json_file
from livox_viz.core.textfile import decode_text
from livox_viz.core.workload import POINT_BUDGET
from livox_viz.motion.flights import BUILTIN_TRAJECTORIES, MAX_SPEED
from livox_viz.motion.imu import MAX_RATE, MIN_RATE
from livox_viz.patterns.stream import points_before
from livox_viz.scene.scenes import list_scenes

#: The grid's lists.
GRID_KEYS = ("sensors", "scenes", "trajectories", "seeds", "returns", "outputs")
#: Options every job of a spec shares, with their defaults.
OPTIONS: dict[str, Any] = {"seconds": 1.0, "frame": "sensor", "trajectory_speed": None, "imu_rate": None,
                           "up": "z", "workers_per_job": None}
#: What one output of a job may be; several are joined by ``+`` (``"las+rosbag"``), at most one file among them.
OUTPUTS = ("npz", "ply", "pcd", "las", "csv", "lvx2", "lvx", "rosbag")
#: A trajectory that does not move.
NO_TRAJECTORY = "none"
#: A return model that is the sensor's own (its LivoxVizReturns, else ideal).
OWN_RETURNS = "own"
#: Jobs a spec may make without ``--force``.
MAX_JOBS = 10_000
#: A spec file is read to at most this many bytes.
MAX_SPEC_BYTES = 1 << 20


class SpecError(LivoxVizError):
    """A batch spec that cannot run: the message names the field and what is allowed."""


@dataclass(frozen=True)
class Job:
    """One scan of a batch.

    Attributes
    ----------
    sensor, scene, trajectory : str
        A preset name or a config file (absolute); a built-in scene or a file (absolute); ``"none"``, a built-in
        flight or a TUM file (absolute).
    seed : int
    returns : str
        ``ideal``, ``datasheet`` or ``own``.
    outputs : tuple of str
        Of :data:`OUTPUTS`.
    options : tuple of (str, value)
        The spec's shared options, sorted.
    """

    sensor: str
    scene: str
    trajectory: str
    seed: int
    returns: str
    outputs: tuple[str, ...]
    options: tuple[tuple[str, Any], ...]

    def parameters(self) -> dict[str, Any]:
        """Everything the job is, as JSON (its hash names it)."""
        return {"sensor": self.sensor, "scene": self.scene, "trajectory": self.trajectory, "seed": self.seed,
                "returns": self.returns, "outputs": "+".join(self.outputs), **dict(self.options)}

    @property
    def name(self) -> str:
        """The job's folder name: what it scans, readable, then 10 hex digits of the hash of all its parameters."""
        digest = hashlib.sha256(json.dumps(self.parameters(), sort_keys=True).encode()).hexdigest()[:10]
        words = [_stem(self.sensor), _stem(self.scene), _stem(self.trajectory), f"s{self.seed}", self.returns,
                 "+".join(self.outputs)]
        readable = re.sub(r"[^A-Za-z0-9_+.-]+", "_", "-".join(words))[:80]
        return f"{readable}-{digest}"

    def output_names(self) -> dict[str, str]:
        """Each output's name in the job's folder: ``cloud.<ext>`` and ``bag``."""
        return {output: "bag" if output == "rosbag" else f"cloud.{output}" for output in self.outputs}


class Grid(Sequence[Job]):
    """Every combination of a spec's lists, in ``itertools.product``'s order (the last list fastest), made one
    job at a time: its count is arithmetic, ``grid[i]`` is computed from ``i``, iterating makes each job as it
    is taken, so memory does not grow with the number of jobs.

    Parameters
    ----------
    axes : tuple of tuple
        The checked values of :data:`GRID_KEYS`, in that order.
    options : tuple of (str, value)
        The spec's shared options, sorted.
    """

    def __init__(self, axes: tuple[tuple[Any, ...], ...], options: tuple[tuple[str, Any], ...]) -> None:
        self.axes = axes
        self.options = options
        #: The number of jobs (a Python int: it may pass what ``len`` can say).
        self.total = math.prod(len(values) for values in axes)
        # Each value's place in its list, to find a job from its parameters (a manifest's row).
        self._places = [{value: place for place, value in enumerate(values)} for values in axes]

    def __len__(self) -> int:
        return self.total

    @overload
    def __getitem__(self, index: int) -> Job: ...

    @overload
    def __getitem__(self, index: slice) -> Sequence[Job]: ...

    def __getitem__(self, index: int | slice) -> Job | Sequence[Job]:
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(self.total))]
        if index < 0:
            index += self.total
        if not 0 <= index < self.total:
            raise IndexError(f"job {index} of a grid of {self.total}")
        values = []
        for axis in reversed(self.axes):
            index, place = divmod(index, len(axis))
            values.append(axis[place])
        return Job(*reversed(values), self.options)

    def __iter__(self) -> Iterator[Job]:
        return (Job(*values, self.options) for values in itertools.product(*self.axes))

    def place_of(self, name: str, parameters: dict[str, Any]) -> int | None:
        """Where the job ``name`` with these parameters (a manifest row's or a record's, values as text or as
        they are) is in the grid, or None when the grid makes no such job (another spec's, or this one's before
        its shared options changed: its name's hash then differs)."""
        try:
            keys = (str(parameters["sensor"]), str(parameters["scene"]), str(parameters["trajectory"]),
                    int(parameters["seed"]), str(parameters["returns"]), tuple(str(parameters["outputs"]).split("+")))
            places = [self._places[axis][key] for axis, key in enumerate(keys)]
        except (KeyError, ValueError, TypeError):
            return None
        if Job(*(axis[at] for axis, at in zip(self.axes, places, strict=True)), self.options).name != name:
            return None
        place = 0
        for axis, at in zip(self.axes, places, strict=True):
            place = place * len(axis) + at
        return place

    def repeated_job(self) -> Job | None:
        """A job the grid makes twice (a value given twice in one list), or None.

        Two jobs share a name exactly when they share all their parameters (the name ends in their hash), which
        is a value repeated in one list: checked list by list, not by naming every job.
        """
        for axis, values in enumerate(self.axes):
            seen: set[Any] = set()
            for value in values:
                if value in seen:
                    return Job(*(value if other == axis else self.axes[other][0] for other in range(len(self.axes))),
                               self.options)
                seen.add(value)
        return None


@functools.lru_cache(maxsize=1024)
def _stem(text: str) -> str:
    """A path's stem, remembered: a grid's jobs share a few sensors, scenes and trajectories, and the stems were
    a third of the cost of naming a job (a rerun names every job of the grid it passes)."""
    return Path(text).stem


def scan_argv(job: Job, folder: Path, workers: int | None) -> list[str]:
    """The ``livox-viz scan`` command line of ``job``, writing into ``folder``."""
    options = dict(job.options)
    sensor = ["--config", job.sensor] if job.sensor.endswith(".json") else ["--preset", job.sensor]
    argv = ["scan", *sensor, "--scene", job.scene, "--seconds", repr(float(options["seconds"])), "--seed",
            str(job.seed), "--frame", options["frame"], "--up", options["up"]]
    if job.returns != OWN_RETURNS:
        argv += ["--returns", job.returns]
    if job.trajectory != NO_TRAJECTORY:
        argv += ["--trajectory", job.trajectory]
        if options["trajectory_speed"] is not None and job.trajectory in BUILTIN_TRAJECTORIES:
            argv += ["--trajectory-speed", repr(float(options["trajectory_speed"]))]
    for output, name in job.output_names().items():
        argv += ["--rosbag", str(folder / name)] if output == "rosbag" else ["--out", str(folder / name)]
    if options["imu_rate"] is not None and "rosbag" in job.outputs:
        argv += ["--imu-rate", repr(float(options["imu_rate"]))]
    if workers is not None:
        argv += ["--workers", str(workers)]
    return argv


def read_spec(path: str | Path, force: bool = False) -> Grid:
    """The jobs of the spec at ``path`` (TOML, or JSON by its suffix), checked whole before any runs.

    The grid is checked list by list, never job by job: its jobs are made (and named) only as they are taken,
    so a grid of 10**7 jobs costs no more to read than one of ten.

    Raises
    ------
    SpecError
        Naming the field and what is allowed: an unknown key, a wrong value, an empty list, a preset or file
        that does not exist, more than :data:`MAX_JOBS` jobs without ``force``, a job of more points than the
        scan's budget without ``force``.
    """
    path = Path(path)
    data = _load(path)
    where = path.name
    unknown = sorted(set(data) - {"grid", *OPTIONS})
    if unknown:
        raise SpecError(f"{where}: unknown key {unknown[0]!r}; allowed: grid, {', '.join(OPTIONS)}")
    grid = data.get("grid")
    if not isinstance(grid, dict):
        raise SpecError(f"{where}: no [grid] table; allowed: a [grid] with {', '.join(GRID_KEYS)} "
                        "(livox-viz batch --example prints one)")
    unknown = sorted(set(grid) - set(GRID_KEYS))
    if unknown:
        raise SpecError(f"{where}: unknown key 'grid.{unknown[0]}'; allowed: {', '.join(GRID_KEYS)}")
    options = _options(data, where)
    base = path.resolve().parent
    lists = {key: _list(grid, key, where) for key in GRID_KEYS}
    sensors = [_sensor(value, base, where) for value in lists["sensors"]]
    scenes = [_scene(value, base, where) for value in lists["scenes"]]
    trajectories = [_trajectory(value, base, where) for value in lists["trajectories"]]
    seeds = [_seed(value, where) for value in lists["seeds"]]
    returns = [_returns(value, where) for value in lists["returns"]]
    outputs = [_outputs(value, where) for value in lists["outputs"]]
    count = math.prod(len(values) for values in lists.values())
    if count > MAX_JOBS and not force:
        raise SpecError(f"{where}: the grid makes {count:,} jobs; allowed: at most {MAX_JOBS:,} (pass --force to "
                        "run more)")
    _check_points(sensors, options["seconds"], where, force)
    grid = Grid((tuple(sensors), tuple(scenes), tuple(trajectories), tuple(seeds), tuple(returns),
                 tuple(outputs)), tuple(sorted(options.items())))
    twice = grid.repeated_job()
    if twice is not None:
        raise SpecError(f"{where}: the grid names one job twice ({twice.name}); allowed: each value once in each list")
    return grid


def _load(path: Path) -> dict[str, Any]:
    if path.is_dir():
        raise SpecError(f"{path}: is a folder; allowed: a TOML or JSON batch spec file (livox-viz batch --example)")
    if not path.is_file():
        raise SpecError(f"{path}: no such spec file; allowed: a TOML or JSON batch spec (livox-viz batch --example)")
    if path.suffix.lower() == ".json":
        data = read_json_file(path, "batch spec")
    else:
        size = path.stat().st_size
        if size > MAX_SPEC_BYTES:
            raise SpecError(f"{path}: {size:,} bytes; allowed: a spec of at most {MAX_SPEC_BYTES:,} bytes")
        try:
            data = tomllib.loads(decode_text(path.read_bytes()))
        except (UnicodeDecodeError, tomllib.TOMLDecodeError) as error:
            raise SpecError(f"{path}: not a readable TOML spec ({error}); allowed: TOML, or JSON named *.json") \
                from None
    if not isinstance(data, dict):
        raise SpecError(f"{path}: a {type(data).__name__}; allowed: a table with a [grid]")
    return data


def _options(data: dict[str, Any], where: str) -> dict[str, Any]:
    options = dict(OPTIONS)
    options.update({key: data[key] for key in OPTIONS if key in data})
    seconds = options["seconds"]
    if isinstance(seconds, bool) or not isinstance(seconds, int | float) or not (
            math.isfinite(seconds) and seconds > 0):
        raise SpecError(f"{where}: seconds = {seconds!r}; allowed: a number of seconds > 0")
    options["seconds"] = float(seconds)
    if options["frame"] not in ("sensor", "world"):
        raise SpecError(f"{where}: frame = {options['frame']!r}; allowed: sensor or world")
    if options["up"] not in ("z", "y"):
        raise SpecError(f"{where}: up = {options['up']!r}; allowed: z or y (a mesh file's up axis)")
    speed = options["trajectory_speed"]
    if speed is not None and (isinstance(speed, bool) or not isinstance(speed, int | float)
                              or not 0 <= speed <= MAX_SPEED):
        raise SpecError(f"{where}: trajectory_speed = {speed!r}; allowed: 0 to {MAX_SPEED:g} m/s")
    rate = options["imu_rate"]
    # The range scan's --imu-rate takes: checked here, or every bag job would fail alone after the batch started.
    if rate is not None and (isinstance(rate, bool) or not isinstance(rate, int | float)
                             or not MIN_RATE <= rate <= MAX_RATE):
        raise SpecError(f"{where}: imu_rate = {rate!r}; allowed: IMU samples per second, {MIN_RATE:g} to "
                        f"{MAX_RATE:g}")
    workers = options["workers_per_job"]
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers <= 1024):
        raise SpecError(f"{where}: workers_per_job = {workers!r}; allowed: a whole number of threads, 1 to 1024")
    return options


def _list(grid: dict[str, Any], key: str, where: str) -> list[Any]:
    values = grid.get(key)
    if values is None:
        raise SpecError(f"{where}: grid.{key} is missing; allowed: a list of at least one value")
    if not isinstance(values, list) or not values:
        raise SpecError(f"{where}: grid.{key} = {values!r:.80}; allowed: a list of at least one value")
    return values


def _text(value: Any, key: str, where: str) -> str:
    if not isinstance(value, str) or not value.strip():
        raise SpecError(f"{where}: grid.{key} holds {value!r:.80}; allowed: names or file paths (text)")
    return value.strip()


def _file(text: str, base: Path) -> Path:
    path = Path(text).expanduser()
    return path if path.is_absolute() else base / path


def _what_it_is(path: Path) -> str:
    """Why ``path`` is no input file, in words: "does not exist", "is a folder" or "is a device, FIFO or socket"
    (``/dev/zero`` as a sensor was said not to exist, the output folder as a scene to be no existing file)."""
    if path.is_dir():
        return "is a folder"
    if path.exists():
        return "is not a regular file (a device, FIFO or socket)"
    return "does not exist"


def _sensor(value: Any, base: Path, where: str) -> str:
    text = _text(value, "sensors", where)
    if text.lower().endswith(".json") or "/" in text or "\\" in text:
        path = _file(text, base)
        if not path.is_file():
            raise SpecError(f"{where}: grid.sensors: {text!r} {_what_it_is(path)}; allowed: a preset name "
                            "(livox-viz presets) or a sensor JSON file (relative to the spec)")
        return str(path.resolve())
    names = sorted({info.name for info in list_presets()})
    if text not in names:
        raise SpecError(f"{where}: grid.sensors: unknown preset {text!r}; allowed: {', '.join(names)}, or a sensor "
                        "JSON file")
    return text


def _scene(value: Any, base: Path, where: str) -> str:
    text = _text(value, "scenes", where)
    names = [name for name, _ in list_scenes()]
    if text in names:
        return text
    path = _file(text, base)
    if not path.is_file():
        what = "" if not path.exists() else f" ({_what_it_is(path).removeprefix('is ')})"
        raise SpecError(f"{where}: grid.scenes: {text!r} is neither a built-in scene ({', '.join(names)}) nor an "
                        f"existing file{what}; allowed: a scene name, a scene JSON or a mesh file (relative to the "
                        "spec)")
    return str(path.resolve())


def _trajectory(value: Any, base: Path, where: str) -> str:
    text = _text(value, "trajectories", where)
    if text in (NO_TRAJECTORY, *BUILTIN_TRAJECTORIES):
        return text
    path = _file(text, base)
    if not path.is_file():
        raise SpecError(f"{where}: grid.trajectories: {text!r} {_what_it_is(path)}; allowed: {NO_TRAJECTORY} (a fixed "
                        f"sensor), {', '.join(BUILTIN_TRAJECTORIES)}, or a TUM file (relative to the spec)")
    return str(path.resolve())


def _seed(value: Any, where: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < 2**63:
        raise SpecError(f"{where}: grid.seeds holds {value!r:.80}; allowed: whole numbers from 0 to 2**63 - 1")
    return value


def _returns(value: Any, where: str) -> str:
    allowed = (*RETURN_MODELS, OWN_RETURNS)
    if value not in allowed:
        raise SpecError(f"{where}: grid.returns holds {value!r:.80}; allowed: {', '.join(allowed)} (own: the "
                        "sensor's own, ideal without one)")
    return value


def _outputs(value: Any, where: str) -> tuple[str, ...]:
    parts = tuple(part.strip().lstrip(".").lower() for part in value.split("+")) if isinstance(value, str) else ()
    files = [part for part in parts if part != "rosbag"]
    if not parts or any(part not in OUTPUTS for part in parts) or len(files) > 1 or len(set(parts)) != len(parts):
        raise SpecError(f"{where}: grid.outputs holds {value!r:.80}; allowed: one of {', '.join(OUTPUTS)}, or a file "
                        "format and rosbag joined by + (e.g. \"las+rosbag\")")
    return parts


def _check_points(sensors: list[str], seconds: float, where: str, force: bool) -> None:
    """Each sensor's scan holds a point and keeps within the scan's point budget (a config that does not load fails
    in its jobs). ``seconds = 1e-300`` passed here, and then every job failed with "holds no point" (issue 47)."""
    for sensor in sensors:
        try:
            config = load_config(sensor) if sensor.endswith(".json") else None
            if config is None:
                from livox_viz.config.presets import load_preset

                config = load_preset(sensor)
        except LivoxVizError:
            continue
        points = points_before(seconds, config.point_rate)
        if points < 1:
            raise SpecError(f"{where}: seconds = {seconds:g} holds no point of {Path(sensor).stem}'s scan; allowed: at "
                            f"least one point's time, {1 / config.point_rate:.3g} s (1 / its point rate)")
        if points > POINT_BUDGET and not force:
            raise SpecError(f"{where}: seconds = {seconds:g} asks {points:,} points of {Path(sensor).stem}'s scan; "
                            f"allowed: at most {POINT_BUDGET:,} a job (pass --force to go on anyway)")


EXAMPLE = '''# livox-viz batch spec: every combination of the [grid]'s lists is one scan job (here 2 x 2 x 1 x 2 x 1 x 1
# = 8 jobs of a second each). Run it:  livox-viz batch --example > spec.toml; livox-viz batch spec.toml --out runs
seconds = 1.0               # every job's scan time
frame = "sensor"            # coordinates of PLY/PCD/LAS/CSV: sensor or world

[grid]
sensors = ["livox_mid70", "livox_mid40"]    # preset names (livox-viz presets) or sensor JSON files
scenes = ["urban", "open_field"]            # built-in scenes (livox-viz scenes), scene JSON or mesh files
trajectories = ["line"]                     # none (fixed), hover, line, circle, figure8, or TUM files
seeds = [0, 1]
returns = ["ideal"]                         # ideal, datasheet, or own (the sensor's own)
outputs = ["npz"]                           # npz ply pcd las csv lvx2 lvx rosbag, or a file and rosbag: "las+rosbag"
'''
