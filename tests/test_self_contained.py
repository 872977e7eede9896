"""What a fresh clone and an installed wheel hold on their own (issue 15 §1).

A user's machine has no development folder beside the checkout: no file of the repository may point
there, and the installed wheel must carry the presets, scenes and public scan
tables that ``fit mid70``, ``compare mid40`` and ``--reference mid70`` name, and the user guide (``docs/``)
that Help > User guide shows.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
#: The development folder beside the checkout (spelled in two parts so this file does not name it).
SIBLING = "../" + "shared"
CHECKED = ("livox_viz", "widgets", "presets", "tests", "benchmarks", "scripts")
TEXT_SUFFIXES = {".py", ".json", ".md", ".txt", ".toml", ".cfg", ".sh", ""}


def repository_text_files() -> list[Path]:
    files = [ROOT / name for name in ("README.md", "Makefile", "pyproject.toml", ".ci/run")]
    files += sorted((ROOT / "docs").glob("*.md"))
    for folder in CHECKED:
        files += [p for p in (ROOT / folder).rglob("*") if p.is_file() and p.suffix in TEXT_SUFFIXES
                  and "__pycache__" not in p.parts]
    return [p for p in files if p.exists()]


def test_no_file_of_the_repository_reads_the_development_folder() -> None:
    files = repository_text_files()
    assert len(files) > 50
    naming = [str(p.relative_to(ROOT)) for p in files
              if SIBLING in p.read_text(encoding="utf-8", errors="replace")]
    assert naming == [], f"these files name {SIBLING}, which a user's machine does not have"


def test_no_help_text_names_the_development_folder() -> None:
    from livox_viz.cli import MODEL_COMMANDS, build_parser, installed_commands

    parser = build_parser([*MODEL_COMMANDS, *installed_commands()])
    texts = [parser.format_help()]
    for action in parser._subparsers._group_actions:  # every command's own --help
        texts += [sub.format_help() for sub in action.choices.values()]
    assert len(texts) > 10
    assert not [t for t in texts if SIBLING in t or "shared" + "/reference" in t]


#: What a build reads from the checkout is copied, never these: setuptools writes build/ and *.egg-info in the
#: tree it builds, so two test processes building this checkout at once broke each other's build (CI, -n 2).
NOT_COPIED = shutil.ignore_patterns(".*", "build", "*.egg-info", "offscreen", "__pycache__")


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The wheel ``pip`` builds from a copy of this checkout (no download: the venv's own setuptools)."""
    source = tmp_path_factory.mktemp("source") / "livox-viz"
    shutil.copytree(ROOT, source, ignore=NOT_COPIED)
    out = tmp_path_factory.mktemp("wheel")
    result = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
                             "-w", str(out), str(source)], capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, f"pip wheel failed:\n{result.stdout}\n{result.stderr}"
    (built,) = out.glob("livox_viz-*.whl")
    return built


@pytest.mark.xdist_group("wheel")
def test_the_wheel_carries_presets_scenes_tables_and_the_window(wheel: Path) -> None:
    names = set(zipfile.ZipFile(wheel).namelist())
    tables = json.loads((ROOT / "presets" / "tables" / "index.json").read_text())
    shipped = {f"livox_viz/shipped_presets/{p.name}" for p in (ROOT / "presets").glob("*.json")}
    shipped |= {f"livox_viz/shipped_presets/scenes/{p.name}" for p in (ROOT / "presets" / "scenes").glob("*.json")}
    shipped |= {f"livox_viz/shipped_presets/tables/{p.name}" for p in (ROOT / "presets" / "tables").iterdir()
                if p.suffix in {".npy", ".json", ".md"}}
    assert {"mid40", "mid70"} <= set(tables)
    assert len(shipped) > 15 and shipped <= names, sorted(shipped - names)
    assert "livox_viz/widgets/app.py" in names and not any(n.startswith("widgets/") for n in names)
    guide = {f"livox_viz/shipped_docs/{p.name}" for p in (ROOT / "docs").glob("*.md")}
    assert "livox_viz/shipped_docs/index.md" in guide and len(guide) >= 5 and guide <= names, sorted(guide - names)


@pytest.mark.xdist_group("wheel")
def test_the_installed_wheel_names_its_tables_without_the_checkout(wheel: Path, tmp_path: Path) -> None:
    """Unpacked away from the checkout, the wheel's own package loads the named tables and presets."""
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    probe = (
        "import livox_viz, sys\n"
        "from livox_viz.fitting.reference import load_reference\n"
        "from livox_viz import load_preset\n"
        f"assert livox_viz.__file__.startswith({str(site)!r}), livox_viz.__file__\n"
        "table = load_reference('mid70')\n"
        "print(len(table.xy_deg), table.rate, load_preset('livox_mid70_risley').point_rate)\n"
        "from livox_viz.widgets.guide import guide_dir\n"
        f"assert str(guide_dir()) == {str((site / 'livox_viz' / 'shipped_docs').resolve())!r}, guide_dir()\n"
    )
    env = {**os.environ, "PYTHONPATH": str(site)}
    result = subprocess.run([sys.executable, "-c", probe], cwd=tmp_path, env=env, capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stderr
    rows, rate, preset_rate = result.stdout.split()
    assert int(rows) > 100_000 and float(rate) == float(preset_rate) == 100_000
