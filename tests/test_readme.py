"""The README is a map (at most 200 lines) that opens with the two commands, `make run` and `make test`
(`.ci/run` calls the second); the manual is in docs/ (mkdocs.yml), and every page the README links exists."""

from __future__ import annotations

import re
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]
README = REPO / "README.md"
MAX_LINES = 200


def test_readme_is_short():
    n = len(README.read_text(encoding="utf-8").splitlines())
    assert n <= MAX_LINES, (f"README.md has {n} lines, at most {MAX_LINES}: manuals go to docs/, results and "
                            f"history to docs/results.md")


def test_readme_starts_with_the_two_commands():
    lines = README.read_text(encoding="utf-8").splitlines()
    first_block = lines.index("```sh")
    assert first_block <= 3, (f"README.md's first code block starts on line {first_block + 1}, expected "
                              f"right under the title")
    block = lines[first_block + 1: lines.index("```", first_block + 1)]
    commands = [line.split("#")[0].strip() for line in block if line.split("#")[0].strip()]
    assert commands == ["make run", "make test"], f"README.md's first code block runs {commands}"


def test_readme_links_and_mkdocs_nav_exist():
    text = README.read_text(encoding="utf-8")
    links = set(re.findall(r"\]\((docs/[^)#]+)", text))
    assert links, "README.md links no page of docs/"
    missing = sorted(link for link in links if not (REPO / link).is_file())
    assert not missing, f"README.md links missing pages: {missing}"
    nav = yaml.safe_load((REPO / "mkdocs.yml").read_text(encoding="utf-8"))["nav"]
    pages = [next(iter(item.values())) for item in nav]
    missing = sorted(p for p in pages if not (REPO / "docs" / p).is_file())
    assert not missing, f"mkdocs.yml nav names missing pages: {missing}"
    unlisted = sorted(p.name for p in (REPO / "docs").glob("*.md") if p.name not in pages)
    assert not unlisted, f"docs/ pages not in mkdocs.yml nav: {unlisted}"
