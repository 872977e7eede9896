"""The README stays a five-minute read, and the user guide (docs/) holds together: every relative link and image
of the README and the guide names a file that exists, and a heading there when it names one; every page of the
guide is reached from its contents; the README's few keys are keys of the key table (issue 45 item 8)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
PAGES = [ROOT / "README.md", *sorted(DOCS.glob("*.md"))]
#: At most this many lines of README.md: what a new user reads in five minutes; the rest is in docs/.
README_LINES = 200
LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(([^)\s]+)\)")


def links(page: Path) -> list[str]:
    """The targets of a Markdown page's links and images, outside code blocks and code spans."""
    text = re.sub(r"^```.*?^```", "", page.read_text(encoding="utf-8"), flags=re.S | re.M)
    text = re.sub(r"`[^`\n]*`", "", text)
    return LINK.findall(text)


def anchors(page: Path) -> set[str]:
    """The anchors GitHub gives a page's headings (written here from GitHub's rule, not taken from the package):
    the heading's text without its Markdown, lower case, punctuation dropped, spaces as hyphens."""
    text = re.sub(r"^```.*?^```", "", page.read_text(encoding="utf-8"), flags=re.S | re.M)
    headings = re.findall(r"^#{1,6} +(.+?) *$", text, flags=re.M)
    return {re.sub(r"[^\w\- ]", "", h.replace("`", "").lower()).replace(" ", "-") for h in headings}


def test_the_readme_is_short_and_starts_with_the_two_commands() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(readme.splitlines()) <= README_LINES, "README.md grew: move the detail into docs/"
    top = readme[: readme.index("\n## ")]
    assert "make run" in top and "make test" in top and ".venv\\Scripts\\livox-viz" in top
    assert "docs/index.md" in readme


def test_the_helpers_find_links_and_anchors(tmp_path: Path) -> None:
    page = tmp_path / "p.md"
    page.write_text("# A `scan`'s files: LVX 1.1\n\n[x](a.md#b) ![i](../s.png) `[no](c.md)`\n```\n[no](d.md)\n```\n"
                    "[t [in] text](e.md) <https://x.org> [w](https://example.org)\n")
    assert links(page) == ["a.md#b", "../s.png", "e.md", "https://example.org"]
    assert anchors(page) == {"a-scans-files-lvx-11"}


@pytest.mark.parametrize("page", PAGES, ids=[str(p.relative_to(ROOT)) for p in PAGES])
def test_every_relative_link_names_a_file_and_heading_that_exist(page: Path) -> None:
    broken = []
    for target in links(page):
        if re.match(r"[a-z]+:", target):  # https:, mailto:
            continue
        path, _, fragment = target.partition("#")
        file = (page.parent / path).resolve() if path else page
        if not file.exists():
            broken.append(f"{target}: no such file")
        elif fragment and file.suffix == ".md" and fragment not in anchors(file):
            broken.append(f"{target}: no such heading in {file.name}")
    assert broken == []


def test_every_page_of_the_guide_is_in_its_contents() -> None:
    named = {Path(t.partition("#")[0]).name for t in links(DOCS / "index.md")}
    assert sorted(p.name for p in DOCS.glob("*.md") if p.name != "index.md" and p.name not in named) == []


def test_the_readmes_keys_are_keys_of_the_key_table() -> None:
    """The README shows a few keys, not the table (docs/window.md has it whole): each is a row of the key table."""
    from livox_viz.widgets.keys import KEYS

    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    table = readme[readme.index("| key | action |"):]
    rows = re.findall(r"^\| (.+?) \| .+ \|$", table[: table.index("\n\n")], flags=re.M)[1:]
    assert 6 <= len(rows) < len(KEYS)
    assert sorted(set(rows) - {row.label for row in KEYS}) == []
