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

__all__ = ["block_in", "replace_block"]


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
