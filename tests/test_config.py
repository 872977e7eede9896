"""The sensor configuration: loading, saving, validation."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from livox_viz import ConfigError, LivoxVizError, SensorConfig, load_config, load_preset, save_config
from livox_viz.config.sensor import JITTER_SCOPE_KEY, PARAM_RANGES

from .conftest import SEED_JSON


def write(path: Path, data: object) -> Path:
    path.write_text(json.dumps(data))
    return path


def test_preset_is_exactly_the_seed_configuration(mid70: SensorConfig) -> None:
    from livox_viz.config.presets import preset_path

    assert json.loads(preset_path("livox_mid70").read_text()) == SEED_JSON
    assert (mid70.data_width, mid70.data_height, mid70.data_check_freq) == (250, 40, 10)
    assert mid70.camera_fov == 70.432
    assert mid70.other_params == (600, 2.956, 1.4, 1.18, 10, 5, 1, 0)
    assert mid70.point_rate == 100_000
    assert mid70.jitter_scope == "flower"


def test_round_trip_keeps_values_unknown_keys_and_order(tmp_path: Path, seed_json: dict) -> None:
    data = {"Comment": "mine", **seed_json, "FutureKey": {"a": [1, 2]}}
    cfg = load_config(write(tmp_path / "in.json", data))
    save_config(cfg, tmp_path / "out.json")
    back = json.loads((tmp_path / "out.json").read_text())
    assert back == data
    assert list(back) == list(data)
    assert load_config(tmp_path / "out.json") == cfg


def test_document_spelling_is_read_and_kept(tmp_path: Path, seed_json: dict) -> None:
    seed_json["SensorAngEuler"] = seed_json.pop("SensorAngEular")
    seed_json["SensorAngEuler"] = [0.1, 0.2, 0.3]
    cfg = load_config(write(tmp_path / "doc.json", seed_json))
    assert cfg.euler_key == "SensorAngEuler"
    assert cfg.sensor_ang_euler == (0.1, 0.2, 0.3)
    saved = cfg.to_json_dict()
    assert "SensorAngEuler" in saved and "SensorAngEular" not in saved


def test_info_says_which_spelling_of_the_mounting_angles_it_read(tmp_path: Path, seed_json: dict,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    """The spec: a loader accepts both spellings "and says which it read"."""
    from livox_viz.cli import main

    document = dict(seed_json)
    document["SensorAngEuler"] = document.pop("SensorAngEular")
    for name, data, spelling in (("rflysim", seed_json, "SensorAngEular (RflySim's"),
                                 ("document", document, "SensorAngEuler (the original document's")):
        path = write(tmp_path / f"{name}.json", data)
        assert main(["info", "--config", str(path)]) == 0
        assert f"read from {spelling}" in capsys.readouterr().out
        assert main(["info", "--config", str(path), "--json"]) == 0
        assert json.loads(capsys.readouterr().out)["mount_angles_key"] == spelling.split()[0]


def test_new_configuration_writes_what_rflysim_expects() -> None:
    data = SensorConfig(other_params=(600, 2.956, 1.4, 1.18, 10, 5, 1)).to_json_dict()
    assert "SensorAngEular" in data
    assert len(data["otherParams"]) == 8 and len(data["SendProtocol"]) == 8
    for key in ("DataWidth", "DataHeight", "DataCheckFreq", "SeqID", "TypeID"):
        assert type(data[key]) is int
    assert JITTER_SCOPE_KEY not in data


def test_jitter_scope_travels_in_an_extra_key(tmp_path: Path, seed_json: dict) -> None:
    seed_json[JITTER_SCOPE_KEY] = "figure"
    cfg = load_config(write(tmp_path / "f.json", seed_json))
    assert cfg.jitter_scope == "figure"
    assert cfg.to_json_dict()[JITTER_SCOPE_KEY] == "figure"


def test_config_json_selects_by_seq_id(tmp_path: Path, seed_json: dict) -> None:
    camera = {"SeqID": 0, "TypeID": 1, "DataWidth": 640}
    second = {**seed_json, "SeqID": 3, "DataWidth": 100}
    path = write(tmp_path / "Config.json", {"VisionSensors": [camera, seed_json, second]})
    assert load_config(path).data_width == 250
    assert load_config(path, seq_id=3).data_width == 100
    seqs = ", ".join(str(s["SeqID"]) for s in (seed_json, second))
    with pytest.raises(ConfigError, match=rf"SeqID 7 in VisionSensors; allowed: .* Livox sensors, .* \({seqs}\)"):
        load_config(path, seq_id=7)


def test_config_json_without_livox(tmp_path: Path) -> None:
    path = write(tmp_path / "Config.json", {"VisionSensors": [{"SeqID": 0, "TypeID": 1}]})
    with pytest.raises(ConfigError, match=r"no Livox sensor.*TypeIDs found: \[1\]"):
        load_config(path)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"DataWidth": 0}, r"DataWidth .* = 0 is out of range; allowed: an integer in \[1, 5000\]"),
        ({"DataWidth": 250.0}, r"DataWidth = 250.0; allowed: an integer"),
        ({"DataWidth": "250"}, r"DataWidth = '250'; allowed: an integer"),
        ({"DataHeight": -1}, r"DataHeight .* out of range"),
        ({"DataCheckFreq": 0}, r"DataCheckFreq .* out of range"),
        ({"CameraFOV": -70}, r"CameraFOV .* = -70.0 is out of range; allowed: \(0, 180\)"),
        ({"CameraFOV": 180}, r"CameraFOV .* out of range; allowed: \(0, 180\)"),
        ({"CameraFOV": "wide"}, r"CameraFOV = 'wide'; allowed: a finite number"),
        ({"otherParams": [600, 2.9, 1.4, 1.18, 10, 5]}, r"otherParams has 6 values; allowed: 7 or 8"),
        ({"otherParams": [600, 2.9, 1.4, 1.18, 10, 5, 1, 0, 9]}, r"otherParams has 9 values"),
        ({"otherParams": [0, 2.9, 1.4, 1.18, 10, 5, 1, 0]}, r"otherParams\[0\] \(max range, m\)"),
        ({"otherParams": [600, 0, 1.4, 1.18, 10, 5, 1, 0]}, r"otherParams\[1\] .* allowed: \(0, 45\]"),
        ({"otherParams": [600, 2.9, -1, 1.18, 10, 5, 1, 0]}, r"otherParams\[2\]"),
        ({"otherParams": [600, 2.9, 1.4, 0, 10, 5, 1, 0]}, r"otherParams\[3\]"),
        ({"otherParams": [600, 2.9, 1.4, 1.18, 0, 5, 1, 0]}, r"otherParams\[4\] .* an integer in \[1, 360\]"),
        ({"otherParams": [600, 2.9, 1.4, 1.18, 2.5, 5, 1, 0]}, r"otherParams\[4\]"),
        ({"otherParams": [600, 2.9, 1.4, 1.18, 10, 0, 1, 0]}, r"otherParams\[5\]"),
        ({"otherParams": [600, 2.9, 1.4, 1.18, 10, 5, -1, 0]}, r"otherParams\[6\] .* allowed: \[0, 360\]"),
        ({"otherParams": "600"}, r"otherParams = '600'; allowed: a JSON list"),
        ({"SendProtocol": [0, 127, 0, 0, 1]}, r"SendProtocol = .*allowed: a list of 8 integers"),
        ({"SensorPosXYZ": [0, 0]}, r"SensorPosXYZ has 2 values; allowed: 3"),
        # 1e308 overflowed the float32 ray casts: a warning, then "no ray hit anything".
        ({"SensorPosXYZ": [1e308, 0, 0]}, r"SensorPosXYZ = .*; allowed: .* each within 1e\+07 m"),
        ({"SensorPosXYZ": [0, 0, -1.0001e7]}, r"SensorPosXYZ = .*; allowed: .* each within 1e\+07 m"),
        # RflySim's request carries these as uint16: info described them, the request failed.
        ({"SeqID": -1}, r"SeqID = -1; allowed: an integer from 0 to 65535"),
        ({"SeqID": 10**30}, r"SeqID = 1000000000000000000000000000000; allowed: an integer from 0 to 65535"),
        ({"TargetCopter": 65536}, r"TargetCopter = 65536; allowed: an integer from 0 to 65535"),
        ({"TargetMountType": -2}, r"TargetMountType = -2; allowed: an integer from 0 to 65535"),
        ({"TypeID": 1}, r"TypeID = 1 is not a Livox lidar; allowed: the Livox TypeIDs are 6 in RflySim SDK v2"),
        ({JITTER_SCOPE_KEY: "petal"}, r"LivoxVizJitterScope = 'petal'; allowed: flower or figure"),
    ],
)
def test_validation_names_field_and_range(tmp_path: Path, seed_json: dict, change: dict, message: str) -> None:
    seed_json.update(change)
    with pytest.raises(ConfigError, match=message):
        load_config(write(tmp_path / "bad.json", seed_json))


@pytest.mark.parametrize("key", ["DataWidth", "otherParams", "CameraFOV", "SendProtocol", "SensorAngEular"])
def test_missing_key_is_named(tmp_path: Path, seed_json: dict, key: str) -> None:
    del seed_json[key]
    with pytest.raises(ConfigError, match=f"missing key '{key}'"):
        load_config(write(tmp_path / "bad.json", seed_json))


@pytest.mark.parametrize("bad", ["NaN", "Infinity", "-Infinity"])
def test_nan_and_infinity_are_rejected(tmp_path: Path, bad: str) -> None:
    text = json.dumps(SEED_JSON).replace("2.956", bad)
    path = tmp_path / "nan.json"
    path.write_text(text)
    # The message names the file, the key and the word.
    with pytest.raises(ConfigError, match=rf"nan.json: otherParams\[1\] = {bad}, which JSON does not allow"):
        load_config(path)


def test_nan_in_python_is_rejected() -> None:
    with pytest.raises(ConfigError, match=r"otherParams\[1\]"):
        SensorConfig(other_params=(600, math.nan, 1.4, 1.18, 10, 5, 1, 0))


def test_malformed_json_names_the_place(tmp_path: Path) -> None:
    path = tmp_path / "broken.json"
    path.write_text('{"TypeID": 6,\n  "DataWidth": }')
    with pytest.raises(ConfigError, match="malformed JSON at line 2 column"):
        load_config(path)


def test_missing_file_and_unknown_preset() -> None:
    with pytest.raises(ConfigError, match="no such file"):
        load_config("/nonexistent/livox.json")
    with pytest.raises(ConfigError, match=r"unknown preset 'nope'; allowed: .*livox_mid70"):
        load_preset("nope")


def test_with_param_validates_and_keeps_the_rest(mid70: SensorConfig) -> None:
    changed = mid70.with_param("petal_height", 4.0)
    assert changed.petal_height == 4.0 and changed.other_params[2:] == mid70.other_params[2:]
    assert mid70.with_param("data_width", 100).data_width == 100
    with pytest.raises(ConfigError, match=r"otherParams\[4\]"):
        mid70.with_param("figure8_per_flower", 0)
    with pytest.raises(ConfigError, match="unknown parameter"):
        mid70.with_param("colour", 1)


def test_every_range_accepts_its_ends_and_rejects_outside() -> None:
    for spec in PARAM_RANGES.values():
        inside_low = spec.low + (1 if spec.integer else 1e-6) * spec.low_open
        inside_high = spec.high - (1 if spec.integer else 1e-6) * spec.high_open
        assert spec.contains(inside_low) and spec.contains(inside_high), spec
        assert not spec.contains(spec.low - 1) and not spec.contains(spec.high + 1), spec
        assert not spec.contains(math.nan)


def test_save_is_atomic_and_keeps_old_file_on_failure(tmp_path: Path, mid70: SensorConfig) -> None:
    target = tmp_path / "keep.json"
    target.write_text("old contents")
    with pytest.raises(LivoxVizError, match="does not exist"):
        save_config(mid70, tmp_path / "missing-folder" / "x.json")
    save_config(mid70, target)
    assert load_config(target) == mid70
    assert [p.name for p in tmp_path.iterdir()] == ["keep.json"]


def test_frame_layout_takes_the_width_asked_up_to_rflysims_limits() -> None:
    """DataWidth may be 5000 and DataHeight 2000 themselves (RflySim's limits): a million points a second at
    10 frames a second with 5000 asked is 5000 x 20 x 10; every layout multiplies back to the rate."""
    from livox_viz.config.sensor import frame_layout

    assert frame_layout(1_000_000, width=5000) == (5000, 20, 10)
    assert frame_layout(1_000_000, width=4000) == (4000, 25, 10)
    assert frame_layout(20_000_000, width=1000) == (1000, 2000, 10)  # DataHeight at its limit, 2000, itself
    for rate, lasers in ((100_000, 1), (240_000, 6), (452_000, 6), (200_000, 4), (10_000_000, 1)):
        w, h, f = frame_layout(rate, lasers)
        assert w * h * f == rate and w <= 5000 and h <= 2000 and f <= 1000
        assert (w * h) % lasers == 0 or rate % lasers != 0  # whole firing groups where the rate allows


def test_a_refusal_names_the_parameter_as_the_panel_does() -> None:
    """The panel said "[1] petal height h" and its refusal "otherParams[1] (petal half-width, deg)": a first-use
    trial took them for two parameters. Each otherParams field's refusal now uses the panel's name."""
    import re

    from livox_viz.config.param_docs import param_doc

    for name, spec in PARAM_RANGES.items():
        if not spec.name.startswith("otherParams"):
            continue
        shown = re.sub(r"^\[\d+\] ", "", param_doc(name).title)
        assert spec.label.split(",")[0] == shown, (name, spec.label, shown)


def test_a_tooltip_names_the_parameter_its_title_names() -> None:
    """The panel's "[1] petal height h" had the tooltip "Half-width of a petal at its middle": a first-use trial
    (issue 45) could not tell whether they were one parameter. A tooltip of RflySim's fields names the symbol its
    title ends in, and the petal height's says what the height is and how it relates to the width."""
    import re

    from livox_viz.config.param_docs import describe, param_doc

    for name, spec in PARAM_RANGES.items():
        symbol = param_doc(name).title.split()[-1]
        if spec.name.startswith(("otherParams", "Data")) and len(symbol) <= 2:
            assert re.search(rf"(?<!\w){re.escape(symbol)}(?!\w)", param_doc(name).help), (name, symbol)
    first = describe("petal_height").split(". ")[0]
    assert first.startswith("Petal height h") and "half the petal's width" in first
