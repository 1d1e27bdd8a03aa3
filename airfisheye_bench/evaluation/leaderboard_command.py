"""``airfisheye-leaderboard``: rank the ``results.json`` of runs, write ``leaderboard.md``/``.csv`` and the page.

The ranking is :mod:`~airfisheye_bench.evaluation.leaderboard`, the page
:mod:`~airfisheye_bench.evaluation.leaderboard_html`; this module reads the command line and writes what they build.
"""

from __future__ import annotations

import sys
from collections.abc import Mapping, Sequence

from airfisheye_bench.errors import report_user_errors
from airfisheye_bench.evaluation.leaderboard import (
    LeaderboardError,
    build_leaderboard,
    find_results,
    load_entries,
)
from airfisheye_bench.evaluation.leaderboard_html import write_html

USAGE = (
    "usage: airfisheye-leaderboard runs=DIR_OR_FILE[,DIR_OR_FILE...] [out=leaderboard] [paper=true] "
    "[skip_invalid=false] [html=FILE.html]"
)
_TRUE, _FALSE = ("1", "true", "yes", "on"), ("0", "false", "no", "off")


def _flag(args: Mapping[str, str], name: str, default: bool) -> bool:
    value = args.get(name, str(default)).strip().lower()
    if value not in _TRUE + _FALSE:
        raise ValueError(f"{name}={args[name]} is not a boolean (true/false)")
    return value in _TRUE


@report_user_errors
def main(argv: Sequence[str] | None = None) -> int:
    """``airfisheye-leaderboard runs=DIR[,DIR] [out=leaderboard] [paper=true] [skip_invalid=false] [html=FILE]``.

    ``html=`` also writes the leaderboard as a self-contained HTML page (sortable tables, a detail view per
    entry); with ``skip_invalid=true`` the invalid files are listed in the markdown and the page.

    Args:
        argv: ``key=value`` arguments (default: ``sys.argv[1:]``).

    Returns:
        0 on success, 1 for missing paths, no results or invalid files, 2 for a usage error.

    Example:
        >>> import tempfile, pathlib
        >>> from airfisheye_bench.evaluation import write_results
        >>> root = pathlib.Path(tempfile.mkdtemp())
        >>> _ = write_results(root / "runs" / "a" / "results.json", "seg", "test", {"mIoU": 0.3})
        >>> main([f"runs={root / 'runs'}", f"out={root / 'board'}"])  # doctest: +ELLIPSIS
        # AirFisheye-bench leaderboard
        ...
        0
        >>> sorted(p.name for p in (root / "board").iterdir())
        ['leaderboard.csv', 'leaderboard.md']
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    bad = [a for a in argv if "=" not in a]
    args = dict(a.split("=", 1) for a in argv if "=" in a)
    unknown = sorted(set(args) - {"runs", "out", "paper", "skip_invalid", "html"})
    if bad or unknown or not args.get("runs", "").strip():
        problem = (
            f"unknown argument(s): {', '.join(bad + unknown)}" if bad or unknown else "runs= is required"
        )
        print(f"{problem}\n{USAGE}", file=sys.stderr)
        return 2
    try:
        paper, skip_invalid = _flag(args, "paper", True), _flag(args, "skip_invalid", False)
    except ValueError as err:
        print(f"{err}\n{USAGE}", file=sys.stderr)
        return 2
    html = args.get("html", "").strip()
    if "html" in args and not html.endswith((".html", ".htm")):
        print(f"html={args['html']} is not an .html file name\n{USAGE}", file=sys.stderr)
        return 2

    runs = [r.strip() for r in args["runs"].split(",") if r.strip()]
    try:
        entries, problems = load_entries(find_results(runs))
    except FileNotFoundError as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    if problems and not skip_invalid:
        print(f"error: {LeaderboardError(problems)}\n(skip_invalid=true leaves them out)", file=sys.stderr)
        return 1
    for problem in problems:
        print(f"warning: skipped invalid results.json: {problem}", file=sys.stderr)
    if not entries:
        print("error: no valid results.json to rank", file=sys.stderr)
        return 1

    board = build_leaderboard(entries, paper=paper, invalid=problems)
    written = list(board.write(args.get("out", "leaderboard")))
    if html:
        written.append(write_html(board, html))
    print(board.to_markdown(), end="")
    print(f"wrote {', '.join(map(str, written))}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
