"""The README and the guides under ``docs/``: every relative link resolves, and the README stays short.

A link is ``[text](target)``, ``![alt](target)`` or a reference definition ``[label]: target``, outside code (fenced
blocks and inline code spans). A target with a scheme (``https:``, ``mailto:``) is not checked; any other must name
a file or folder of the repository, and its ``#anchor``, in a markdown file, a heading of that file as GitHub slugs
it (or an ``id`` / ``name`` of an HTML anchor).
"""

from __future__ import annotations

import re
import unicodedata
from pathlib import Path
from urllib.parse import unquote

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DOCUMENTS = [README, *sorted((ROOT / "docs").glob("*.md"))]
README_MAX_LINES = 220

_FENCE = re.compile(r"^\s{0,3}(`{3,}|~{3,})")
_CODE_SPAN = re.compile(r"(`+)(.+?)\1")
_INLINE_LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]*)>?(?:\s+\"[^\"]*\")?\s*\)")
_REFERENCE = re.compile(r"^\s{0,3}\[[^\]]+\]:\s*<?(\S+?)>?(?:\s+.*)?$")
_HEADING = re.compile(r"^\s{0,3}(#{1,6})\s+(.*?)\s*#*\s*$")
_HTML_ANCHOR = re.compile(r"<a\s[^>]*\b(?:id|name)\s*=\s*\"([^\"]+)\"", re.IGNORECASE)
_SCHEME = re.compile(r"^[a-zA-Z][a-zA-Z0-9+.-]*:")


def _prose_lines(text: str) -> list[tuple[int, str]]:
    """``(line number, line)`` of the lines outside fenced code blocks."""
    lines, fence = [], None
    for number, line in enumerate(text.splitlines(), start=1):
        match = _FENCE.match(line)
        if fence is None and match:
            fence = match.group(1)
        elif (
            fence is not None
            and match
            and match.group(1)[0] == fence[0]
            and len(match.group(1)) >= len(fence)
        ):
            fence = None
        elif fence is None:
            lines.append((number, line))
    return lines


def _heading_text(raw: str) -> str:
    """A heading as it renders: links by their text, code spans by their content, emphasis markers dropped."""
    text = _CODE_SPAN.sub(lambda m: m.group(2).strip(), raw)
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", text)
    text = re.sub(r"<[^>]+>", "", text)
    return re.sub(r"(\*+|(?<!\w)_+|_+(?!\w))", "", text)


def github_slug(heading: str) -> str:
    """The anchor GitHub gives a heading (github-slugger): lower case, punctuation dropped, spaces to hyphens.

    Example:
        >>> github_slug("Resume and DDP: what is guaranteed"), github_slug("Configuration groups (`configs/`)")
        ('resume-and-ddp-what-is-guaranteed', 'configuration-groups-configs')
        >>> github_slug("AirSim360 / Omni360-X"), github_slug("Data loading (`AirFisheyeDataset`)")
        ('airsim360--omni360-x', 'data-loading-airfisheyedataset')
    """
    kept = []
    for char in _heading_text(heading).lower():
        category = unicodedata.category(char)
        if char in " -" or category[0] in "LM" or category in ("Nd", "Nl", "Pc"):
            kept.append(char)
    return "".join(kept).replace(" ", "-")


def anchors(path: Path) -> set[str]:
    """Every anchor a reader can link to in ``path``: its headings' slugs (repeats numbered ``-1``, ``-2``, as
    GitHub numbers them) and its HTML anchors."""
    found: set[str] = set()
    seen: dict[str, int] = {}
    for _, line in _prose_lines(path.read_text(encoding="utf-8")):
        found.update(_HTML_ANCHOR.findall(line))
        match = _HEADING.match(line)
        if not match:
            continue
        slug = github_slug(match.group(2))
        count = seen.get(slug, 0)
        seen[slug] = count + 1
        found.add(slug if count == 0 else f"{slug}-{count}")
    return found


def links(path: Path) -> list[tuple[int, str]]:
    """``(line number, target)`` of every link of ``path`` outside code."""
    found = []
    for number, line in _prose_lines(path.read_text(encoding="utf-8")):
        prose = _CODE_SPAN.sub("", line)
        found += [(number, target) for target in _INLINE_LINK.findall(prose)]
        reference = _REFERENCE.match(prose)
        if reference:
            found.append((number, reference.group(1)))
    return found


def broken_links(path: Path, root: Path = ROOT) -> list[str]:
    """The relative links of ``path`` whose file, folder or anchor does not exist (or lies outside ``root``), each
    with its line."""
    problems = []
    for number, target in links(path):
        if not target or _SCHEME.match(target):
            continue
        name, _, anchor = target.partition("#")
        where = (path.parent / unquote(name)).resolve() if name else path
        place = f"{path.relative_to(root)}:{number}: {target}"
        if not where.is_relative_to(root.resolve()):
            problems.append(f"{place}: outside the repository")
        elif not where.exists():
            problems.append(f"{place}: no such file or folder")
        elif anchor and where.suffix == ".md" and unquote(anchor) not in anchors(where):
            problems.append(f"{place}: no heading with that anchor")
    return problems


@pytest.mark.parametrize("path", DOCUMENTS, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_resolves(path: Path) -> None:
    assert links(path) or path != README, "the README links to nothing"
    assert broken_links(path) == []


def test_the_readme_is_short() -> None:
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= README_MAX_LINES, (
        f"README.md has {len(lines)} lines (at most {README_MAX_LINES}): move the detail to a guide under docs/"
    )


def test_the_link_checker_finds_a_broken_file_and_anchor(tmp_path: Path) -> None:
    (tmp_path / "guide.md").write_text("# A guide\n\n## Two `words` (here)\n\n## Two words here\n")
    doc = tmp_path / "doc.md"
    doc.write_text(
        "[ok](guide.md#two-words-here) [ok](guide.md#two-words-here-1) [ok](#top)\n"
        "[bad](guide.md#missing) ![bad](figures/none.png) `[code](nowhere.md)` [web](https://example.org)\n"
        '```\n[fenced](nowhere.md)\n```\n<a id="top"></a>\n'
    )
    assert broken_links(doc, tmp_path) == [
        "doc.md:2: guide.md#missing: no heading with that anchor",
        "doc.md:2: figures/none.png: no such file or folder",
    ]
