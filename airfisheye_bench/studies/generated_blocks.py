r"""Generated blocks of the Markdown reports: the text between a ``begin`` and an ``end`` marker line, rewritten from
a committed record by the script the ``begin`` marker names (and checked against it by the tests), never by hand.

Example:
    >>> text = "a\n<!-- x:begin -->\nold\n<!-- x:end -->\nb"
    >>> new = replace_block(text, "new", "<!-- x:begin -->", "<!-- x:end -->")
    >>> new.splitlines()
    ['a', '<!-- x:begin -->', 'new', '<!-- x:end -->', 'b']
    >>> block_in(new, "<!-- x:begin -->", "<!-- x:end -->")
    'new'
"""

from __future__ import annotations

from pathlib import Path

from airfisheye_bench.atomic import atomic_write_text

__all__ = ["block_in", "replace_block", "write_block"]


def replace_block(text: str, block: str, begin: str, end: str) -> str:
    """``text`` with the part between the markers ``begin`` and ``end`` replaced by ``block``; a ``ValueError``
    when the text lacks them."""
    try:
        head, rest = text.split(begin, 1)
        _, tail = rest.split(end, 1)
    except ValueError:
        raise ValueError(f"the text has no generated-block markers ({begin} ... {end})") from None
    return f"{head}{begin}\n{block}\n{end}{tail}"


def block_in(text: str, begin: str, end: str) -> str:
    """The generated block between the markers ``begin`` and ``end`` of ``text``."""
    try:
        return text.split(begin, 1)[1].split(end, 1)[0].strip("\n")
    except IndexError:
        raise ValueError(f"the text has no generated-block markers ({begin} ... {end})") from None


def write_block(
    path: Path, block: str, begin: str, end: str, *, section: str, before: str | None = None
) -> None:
    """Rewrite the generated block of the Markdown file ``path``; the text around it (its record's citation, the
    judgement of the numbers) stays. A file without the markers gets the heading ``section`` with the block, before
    the heading line ``before`` (else at the end). One atomic write."""
    text = path.read_text(encoding="utf-8")
    if begin in text:
        text = replace_block(text, block, begin, end)
    else:
        new = f"{section}\n\n{begin}\n{block}\n{end}\n"
        lines = text.split("\n")
        if before is not None and before in lines:
            at = lines.index(before)
            text = "\n".join([*lines[:at], *new.split("\n"), *lines[at:]])
        else:
            text = text.rstrip("\n") + "\n\n" + new
    atomic_write_text(path, text)
