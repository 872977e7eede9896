"""Text files as Windows tools save them: every reader of a user's text (a sensor config, a scene, a batch spec in
JSON or TOML, a TUM trajectory, a Livox CSV table) reads UTF-8 with Notepad's byte-order mark and UTF-16 with its
mark (Windows PowerShell 5.1's ``>`` and ``Out-File``) as the plain UTF-8 file, and refuses broken text in one
line naming the file."""

from __future__ import annotations

import codecs
import io
from pathlib import Path

import numpy as np
import pytest

from livox_viz.cli.batch_spec import read_spec
from livox_viz.config.presets import shipped_preset_dir
from livox_viz.config.sensor import load_config
from livox_viz.core.errors import LivoxVizError
from livox_viz.core.jsonfile import read_json_file
from livox_viz.core.textfile import decode_text, utf8_blocks
from livox_viz.fitting.reference import load_reference
from livox_viz.motion.tum import load_tum
from livox_viz.scene.scenes import load_scene

#: How Windows tools encode a text: name -> bytes of it.
ENCODINGS = {
    "utf-8": lambda text: text.encode("utf-8"),
    "utf-8 with Notepad's mark": lambda text: codecs.BOM_UTF8 + text.encode("utf-8"),
    "utf-16 (PowerShell 5.1)": lambda text: codecs.BOM_UTF16_LE + text.encode("utf-16-le"),
    "utf-16 big-endian": lambda text: codecs.BOM_UTF16_BE + text.encode("utf-16-be"),
}


def _saved(tmp_path: Path, name: str, text: str) -> dict[str, Path]:
    """``text`` saved in each of :data:`ENCODINGS`, each in its own folder under the same file name."""
    paths = {}
    for k, (encoding, encode) in enumerate(ENCODINGS.items()):
        folder = tmp_path / f"e{k}"
        folder.mkdir()
        paths[encoding] = folder / name
        paths[encoding].write_bytes(encode(text))
    return paths


def test_the_decoder_against_pythons_own_codecs() -> None:
    """Non-ASCII text (degrees, CJK: a scene description in the original document's language) round-trips through
    every encoding, and a UTF-16 file cut mid-character is refused."""
    text = "扫描 30° — ok\n"
    for encode in ENCODINGS.values():
        assert decode_text(encode(text)) == text
    with pytest.raises(UnicodeDecodeError):
        decode_text(codecs.BOM_UTF16_LE + text.encode("utf-16-le")[:-1])


@pytest.mark.parametrize("block", [1, 2, 3, 7, 64])
def test_streamed_blocks_join_to_the_text_whatever_the_block_size(block: int) -> None:
    """A UTF-16 stream decoded in blocks that cut characters (odd sizes, a surrogate pair cut in two) gives the
    UTF-8 bytes of the whole text, without a mark; a UTF-8 file's blocks are its bytes without the mark."""
    text = "t x 😀 é\n" * 5
    for encode in ENCODINGS.values():
        joined = b"".join(utf8_blocks(io.BytesIO(encode(text)), block))
        assert joined == text.encode("utf-8")
    assert b"".join(utf8_blocks(io.BytesIO(b""), block)) == b""


def test_a_sensor_config_in_each_encoding(tmp_path: Path) -> None:
    source = (shipped_preset_dir() / "livox_mid70.json").read_text(encoding="utf-8")
    configs = {name: load_config(path) for name, path in _saved(tmp_path, "mid70.json", source).items()}
    plain = configs.pop("utf-8")
    for name, config in configs.items():
        assert config == plain, name


def test_a_scene_in_each_encoding(tmp_path: Path) -> None:
    text = ('{"LivoxVizDescription": "a box, 扫描", "objects": [{"type": "box", "size": [2, 2, 2], '
            '"center": [10, 0, -1], "name": "箱子"}]}')
    meshes = {name: load_scene(path) for name, path in _saved(tmp_path, "scene.json", text).items()}
    plain = meshes.pop("utf-8")
    assert len(plain.faces) > 0
    for name, mesh in meshes.items():
        np.testing.assert_array_equal(mesh.vertices, plain.vertices, err_msg=name)


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_a_batch_spec_in_each_encoding(tmp_path: Path, suffix: str) -> None:
    toml = ('seconds = 0.5  # 扫描\n[grid]\nsensors = ["livox_mid40"]\nscenes = ["urban"]\n'
            'trajectories = ["none"]\nseeds = [1, 2]\nreturns = ["ideal"]\noutputs = ["npz"]\n')
    json = ('{"seconds": 0.5, "grid": {"sensors": ["livox_mid40"], "scenes": ["urban"], "trajectories": ["none"], '
            '"seeds": [1, 2], "returns": ["ideal"], "outputs": ["npz"]}}')
    text = toml if suffix == ".toml" else json
    specs = {name: read_spec(path) for name, path in _saved(tmp_path, "spec" + suffix, text).items()}
    plain = specs.pop("utf-8")
    for name, spec in specs.items():
        assert [job.name for job in spec] == [job.name for job in plain], name


def test_a_tum_trajectory_in_each_encoding_and_over_many_blocks(tmp_path: Path, monkeypatch) -> None:
    """Read in blocks of 1 KiB, so the UTF-16 file's lines and characters are cut between blocks."""
    import livox_viz.motion.tum as tum

    monkeypatch.setattr(tum, "_BLOCK_BYTES", 1023)
    text = "# t x y z qx qy qz qw\n" + "".join(f"{t / 10} {t} 0.5 -2 0 0 0 1\n" for t in range(300))
    read = {name: load_tum(path) for name, path in _saved(tmp_path, "flight.tum", text).items()}
    plain = read.pop("utf-8")
    assert plain.t.size == 300
    for name, trajectory in read.items():
        np.testing.assert_array_equal(trajectory.t, plain.t, err_msg=name)
        np.testing.assert_array_equal(trajectory.position, plain.position, err_msg=name)


def test_a_livox_csv_in_each_encoding(tmp_path: Path) -> None:
    rows = "".join(f"{k * 1e-5:.6f},{k * 0.1:.3f},{90 - k * 0.05:.3f}\n" for k in range(200))
    text = "Time/s,Azimuth/deg,Zenith/deg\n" + rows
    tables = {name: load_reference(path, rate=1e5) for name, path in _saved(tmp_path, "table.csv", text).items()}
    plain = tables.pop("utf-8")
    for name, table in tables.items():
        np.testing.assert_array_equal(table.xy_deg, plain.xy_deg, err_msg=name)


@pytest.mark.parametrize(("name", "reader", "message"), [
    ("bad.json", read_json_file, r"bad.json: not text \(byte \d+: truncated data\); allowed: JSON in UTF-8"),
    ("bad.tum", load_tum, r"bad.tum: not text \(truncated data\); allowed: a TUM trajectory .* or UTF-16 with its"),
])
def test_broken_utf16_is_one_line_naming_the_file(tmp_path: Path, name: str, reader, message: str) -> None:
    """A UTF-16 file with an odd last byte (cut short)."""
    path = tmp_path / name
    path.write_bytes(codecs.BOM_UTF16_LE + "0 0 0 0 0 0 0 1\n".encode("utf-16-le") + b"\x00")
    with pytest.raises(LivoxVizError, match=message) as caught:
        reader(path)
    assert "\n" not in str(caught.value)
