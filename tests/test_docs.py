"""The documentation holds together: every relative link resolves, headings included, and the README stays short."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
LINK = re.compile(r"\]\(([^)\s]+)\)")
README_MAX_LINES = 250


def pages(root: Path) -> list[Path]:
    return [root / "README.md", *sorted((root / "docs").rglob("*.md"))]


def anchor(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def anchors(page: Path) -> set[str]:
    return {anchor(line.lstrip("#")) for line in page.read_text().splitlines() if line.startswith("#")}


def broken_links(root: Path) -> list[str]:
    """``page: target`` of every relative link whose file or heading does not exist."""
    broken = []
    for page in pages(root):
        for target in LINK.findall(page.read_text()):
            if re.match(r"[a-z]+:", target):  # http:, https:, mailto:
                continue
            path, _, heading = target.partition("#")
            linked = (page.parent / path).resolve() if path else page
            if not linked.exists() or (heading and linked.suffix == ".md" and heading not in anchors(linked)):
                broken.append(f"{page.relative_to(root)}: {target}")
    return broken


def test_every_relative_link_resolves():
    assert broken_links(ROOT) == []


def test_the_link_check_finds_a_missing_page_and_a_missing_heading(tmp_path):
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "game.md").write_text("# The game\n\n## Scripted players\n")
    (tmp_path / "README.md").write_text(
        "[ok](docs/game.md#scripted-players) [web](https://example.org/x) [gone](docs/gone.md) [bad](docs/game.md#rules)\n"
    )
    assert broken_links(tmp_path) == ["README.md: docs/gone.md", "README.md: docs/game.md#rules"]


def test_the_readme_is_short():
    assert len((ROOT / "README.md").read_text().splitlines()) < README_MAX_LINES


def test_every_results_page_stays_under_200_lines():
    # A page is one result (question, answer, command, table, figure, machine and commit); its history is in git.
    long = {page.name: n for page in (ROOT / "docs" / "results").glob("*.md") if (n := len(page.read_text().splitlines())) >= 200}
    assert long == {}
