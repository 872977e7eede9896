"""RflySim SDK v3's configurations: TypeID 22 (the rosette) and 23 (the Mid-360), the v3 form's EularOrQuat,
SensorAngQuat and sixteen otherParams, and writing a configuration for either SDK.

What RflySim's v3 client (``VisionCaptureApi.jsonLoad``, public copies such as Ding-Guo/RflySimVision
``sensor_pkg/VisionCaptureApi.py``) accepts is mirrored by :func:`rflysim_v3_accepts`, written from its rules:
integers where it wants them, 8 SendProtocol values, 3 SensorPosXYZ and SensorAngEular values, and with
``EularOrQuat`` 4 SensorAngQuat values and exactly 16 otherParams, without it exactly 8.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from livox_viz import ConfigError, SensorConfig, load_config, load_preset, save_config
from livox_viz.cli import main
from livox_viz.config.mount import sensor_mount
from livox_viz.config.sensor import MID360_FRAME, mid360_track
from livox_viz.core.rotations import euler_matrix
from livox_viz.patterns.factory import make_pattern

from .conftest import SEED_JSON

V3_ROSETTE = {
    "SeqID": 0, "TypeID": 22, "TargetCopter": 1, "TargetMountType": 0,
    "DataWidth": 250, "DataHeight": 40, "DataCheckFreq": 10,
    "SendProtocol": [1, 127, 0, 0, 1, 9999, 0, 0],
    "CameraFOV": 70.432, "SensorPosXYZ": [0, 0, -0.3],
    "EularOrQuat": 0, "SensorAngEular": [0, 0, 0], "SensorAngQuat": [0, 0, 0, 0],
    "otherParams": [600, 2.956, 1.4, 1.18, 10, 5, 1, 0, 0, 0, 0, 0, 0, 3.5, 0, 7],
    "MyNote": {"kept": True},
}
#: RflySim's own Mid-360 example (its sensor page, v3.08), comments taken out: the old form with TypeID 23.
V3_MID360_EXAMPLE = {
    "SeqID": 0, "TypeID": 23, "TargetCopter": 1, "TargetMountType": 0,
    "DataWidth": 64, "DataHeight": 272, "DataCheckFreq": 10,
    "SendProtocol": [0, 127, 0, 0, 1, 9999, 0, 0],
    "CameraFOV": 0, "SensorPosXYZ": [0, 0, -0.3], "SensorAngEular": [0, 0, 0],
    "otherParams": [100, 0, 0, 0, 0, 0, 0, 0],
}


def rflysim_v3_accepts(sensor: dict) -> bool:
    """The rules of RflySim's v3 ``jsonLoad`` for one VisionSensors entry (its "Json data format is wrong!")."""
    for key in ("SeqID", "TypeID", "TargetCopter", "TargetMountType", "DataWidth", "DataHeight", "DataCheckFreq"):
        if not isinstance(sensor[key], int):
            return False
    if not isinstance(sensor["CameraFOV"], (int, float)) or len(sensor["SendProtocol"]) != 8:
        return False
    if len(sensor["SensorPosXYZ"]) != 3 or len(sensor["SensorAngEular"]) != 3:
        return False
    if "EularOrQuat" in sensor:
        return len(sensor["SensorAngQuat"]) == 4 and len(sensor["otherParams"]) == 16
    return len(sensor["otherParams"]) == 8


def write(path: Path, data: object) -> Path:
    path.write_text(json.dumps(data))
    return path


def test_a_v3_rosette_is_the_v2_rosette(tmp_path: Path) -> None:
    v3 = load_config(write(tmp_path / "v3.json", V3_ROSETTE))
    v2 = load_config(write(tmp_path / "v2.json", SEED_JSON))
    assert (v3.sdk, v3.v3_form, v2.sdk, v2.v3_form) == ("v3", True, "v2", False)
    assert v3.other_params[:8] == v2.other_params and v3.other_params[13] == 3.5 and len(v3.other_params) == 16
    assert v3.mount_quaternion is None  # EularOrQuat 0: the Euler angles are the mount ([0, 0, 0, 0] unused)
    ours, theirs = make_pattern(v3, seed=4).take(30_000), make_pattern(v2, seed=4).take(30_000)
    np.testing.assert_array_equal(ours.xy_deg, theirs.xy_deg)


def test_save_writes_v3_back_as_v3_keys_order_and_extras(tmp_path: Path) -> None:
    cfg = load_config(write(tmp_path / "in.json", V3_ROSETTE))
    save_config(cfg, tmp_path / "out.json")
    back = json.loads((tmp_path / "out.json").read_text())
    assert back == V3_ROSETTE and list(back) == list(V3_ROSETTE)
    assert rflysim_v3_accepts(back)


def test_rflysims_mid360_example_scans_the_mid360_track(tmp_path: Path) -> None:
    cfg = load_config(write(tmp_path / "mid360.json", V3_MID360_EXAMPLE))
    track, fov = mid360_track()
    assert (cfg.sdk, cfg.v3_form, cfg.pattern_model, cfg.track, cfg.fov) == ("v3", False, "track", track, fov)
    assert cfg.range_max == 100 and cfg.pattern_plane == "panorama"
    assert (cfg.data_width, cfg.data_height) == MID360_FRAME and cfg.point_rate == 64 * 272 * 10
    chunk = make_pattern(cfg).take(20_000)
    assert np.ptp(chunk.xy_deg[:, 0]) > 300  # all the way round
    # Written back as RflySim wrote it: none of our keys, its W x H as they were.
    assert cfg.to_json_dict() == V3_MID360_EXAMPLE
    odd = {**V3_MID360_EXAMPLE, "DataWidth": 500, "DataHeight": 40}
    cfg = load_config(write(tmp_path / "odd.json", odd))
    assert cfg.points_per_frame == 64 * 272 and cfg.to_json_dict() == odd


def test_a_quaternion_mount_is_the_rotation_it_names(tmp_path: Path) -> None:
    roll, pitch, yaw = 0.3, -0.5, 2.0
    half = [a / 2 for a in (roll, pitch, yaw)]
    cr, sr, cp, sp, cy, sy = (f(a) for a in half for f in (math.cos, math.sin))
    wxyz = [cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy]
    data = {**V3_ROSETTE, "EularOrQuat": 1, "SensorAngQuat": [3 * v for v in wxyz], "SensorAngEular": [9, 9, 9]}
    cfg = load_config(write(tmp_path / "q.json", data))
    mount = sensor_mount(cfg)
    np.testing.assert_allclose(mount.rotation, euler_matrix(roll, pitch, yaw), atol=1e-12)
    np.testing.assert_allclose(mount.origin, [0, 0, -0.3])
    # 0.5 exactly is still the Euler angles (the SDK: "> 0.5 is the quaternion").
    cfg = load_config(write(tmp_path / "e.json", {**data, "EularOrQuat": 0.5}))
    np.testing.assert_allclose(sensor_mount(cfg).rotation, euler_matrix(9, 9, 9), atol=1e-12)


@pytest.mark.parametrize(("change", "message"), [
    ({"otherParams": [600, 2.956, 1.4, 1.18, 10, 5, 1, 0]},
     r"^v3\.json: otherParams has 8 values; allowed: exactly 16 in a configuration with EularOrQuat"),
    ({"otherParams": [600] + [1] * 16}, r"otherParams has 17 values; allowed: exactly 16"),
    ({"EularOrQuat": 1, "SensorAngQuat": [0, 0, 0, 0]},
     r"SensorAngQuat = \[0, 0, 0, 0\] has zero length.*allowed: a rotation quaternion \[w, x, y, z\] of non-zero"),
    ({"EularOrQuat": 1, "SensorAngQuat": [1, 0, "x", 0]}, r"SensorAngQuat\[2\] = 'x'; allowed: a finite number"),
    ({"SensorAngQuat": [1, 0, 0]}, r"SensorAngQuat has 3 values; allowed: 4 finite numbers"),
    ({"EularOrQuat": "yes"}, r"EularOrQuat = 'yes'; allowed: a number \(> 0\.5: the mount is SensorAngQuat"),
    ({"EularOrQuat": None}, r"EularOrQuat = None; allowed: a number"),
    ({"TypeID": 20}, r"TypeID = 20 \(a mechanical lidar .*\) is not a Livox lidar; allowed: the Livox TypeIDs are 6 "
                     r"in RflySim SDK v2 \(the rosette\) and 22 \(the rosette\) or 23 \(the Mid-360\) in SDK v3"),
    ({"TypeID": 21}, r"TypeID = 21 \(a mechanical lidar .*\) is not a Livox lidar; allowed: the Livox TypeIDs"),
    ({"TypeID": 6}, r"TypeID = 6 with EularOrQuat .* sound sensor of SDK v3.*allowed: the Livox TypeIDs are 6 in"),
    # Issue 47: accepted by info and save, then a traceback in request ("float too large to pack with f format").
    ({"EularOrQuat": 1e300, "SensorAngQuat": [1, 0, 0, 0]},
     r"EularOrQuat = 1e\+300; allowed: a number .* within the 32-bit float RflySim reads it as, \+-3\.403e\+38"),
    ({"EularOrQuat": 1, "SensorAngQuat": [1e300, 1e300, 0, 0]},
     r"SensorAngQuat\[0\] = 1e\+300 does not fit the 32-bit float RflySim reads it as; allowed: a number within"),
])
def test_bad_v3_input_is_one_line_naming_the_field(tmp_path: Path, change: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message) as caught:
        load_config(write(tmp_path / "v3.json", {**V3_ROSETTE, **change}))
    assert "\n" not in str(caught.value)


def test_missing_quaternion_and_sixteen_without_the_switch_are_refused(tmp_path: Path) -> None:
    without = {k: v for k, v in V3_ROSETTE.items() if k != "SensorAngQuat"}
    with pytest.raises(ConfigError, match=r"missing key 'SensorAngQuat'; a configuration with EularOrQuat"):
        load_config(write(tmp_path / "a.json", without))
    old_form = {k: v for k, v in V3_ROSETTE.items() if k not in ("SensorAngQuat", "EularOrQuat")}
    with pytest.raises(ConfigError, match=r"otherParams has 16 values; allowed: 7 or 8 .* or 16 with EularOrQuat"):
        load_config(write(tmp_path / "b.json", old_form))
    with pytest.raises(ConfigError, match=r"NaN|nan"):
        SensorConfig.from_json_dict({**V3_ROSETTE, "EularOrQuat": 1, "SensorAngQuat": [math.nan, 0, 0, 1]})


def test_a_v3_config_json_skips_the_sound_sensor(tmp_path: Path) -> None:
    sound = {**V3_ROSETTE, "SeqID": 1, "TypeID": 6}
    path = write(tmp_path / "Config.json", {"VisionSensors": [sound, {**V3_ROSETTE, "SeqID": 2}]})
    assert load_config(path).seq_id == 2
    path = write(tmp_path / "Only.json", {"VisionSensors": [sound]})
    with pytest.raises(ConfigError, match=r"no Livox sensor \(TypeID 6, 22 or 23; 6 only without EularOrQuat\)"):
        load_config(path)


@pytest.mark.parametrize("preset", ["livox_mid70", "livox_mid70_risley", "livox_mid360"])
def test_with_sdk_round_trips_and_rflysim_accepts_both(preset: str) -> None:
    cfg = load_preset(preset)
    v3 = cfg.with_sdk("v3")
    assert v3.v3_form and v3.sdk == "v3" and rflysim_v3_accepts(v3.to_json_dict())
    assert v3.type_id == (23 if preset == "livox_mid360" else 22)
    keys = list(v3.to_json_dict())
    assert keys.index("SensorPosXYZ") + 1 == keys.index("EularOrQuat")  # where RflySim's files have them
    assert keys.index("SensorAngEular") + 1 == keys.index("SensorAngQuat")
    if preset == "livox_mid360":
        with pytest.raises(ConfigError, match=r"SDK v2 has no Mid-360 \(TypeID 23\); allowed: --sdk v3"):
            v3.with_sdk("v2")
        return
    assert v3.with_sdk("v2").to_json_dict() == cfg.to_json_dict()
    assert rflysim_v3_accepts(cfg.to_json_dict())  # the old form: what v3's client still reads


def test_v2_has_no_room_for_otherparams_past_eight(tmp_path: Path) -> None:
    cfg = load_config(write(tmp_path / "v3.json", V3_ROSETTE))
    with pytest.raises(ConfigError, match=r"otherParams\[8\.\.15\] = \[0, 0, 0, 0, 0, 3\.5, 0, 7\]: SDK v2 has room "):
        cfg.with_sdk("v2")


def test_a_quaternion_mount_written_for_v2_keeps_its_rotation(tmp_path: Path) -> None:
    data = {**V3_ROSETTE, "EularOrQuat": 1, "SensorAngQuat": [0.9, 0.1, -0.3, 0.2], "otherParams": [600, 2.956, 1.4,
            1.18, 10, 5, 1, 0] + [0] * 8}
    cfg = load_config(write(tmp_path / "q.json", data))
    v2 = cfg.with_sdk("v2")
    assert "SensorAngQuat" not in v2.to_json_dict() and v2.type_id == 6
    np.testing.assert_allclose(sensor_mount(v2).rotation, sensor_mount(cfg).rotation, atol=1e-12)


def test_save_command_writes_either_sdk(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "Config_v3.json"
    assert main(["save", "--preset", "livox_mid70", "--sdk", "v3", "--out", str(out)]) == 0
    assert "TypeID 22, RflySim SDK v3" in capsys.readouterr().out
    written = json.loads(out.read_text())
    assert written["TypeID"] == 22 and len(written["otherParams"]) == 16 and rflysim_v3_accepts(written)
    back = tmp_path / "back.json"
    assert main(["save", "--config", str(out), "--sdk", "v2", "--out", str(back)]) == 0
    assert json.loads(back.read_text()) == load_preset("livox_mid70").to_json_dict()
    assert main(["save", "--config", str(tmp_path / "nothing.json"), "--sdk", "v3", "--out", str(back)]) == 2
    assert main(["fit", "--to", "livox_mid70_risley", "--sdk", "v3"]) == 2
    assert "give --out too" in capsys.readouterr().err
