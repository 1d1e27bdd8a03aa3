"""Run a console command in the test process and get its exit status, whether it returns it or exits."""

from __future__ import annotations

from collections.abc import Callable, Sequence


def exit_status(command: Callable[[Sequence[str]], int], argv: Sequence[str]) -> int:
    """``command(argv)``'s exit status: its return value, or the code of the ``SystemExit`` it raised.

    A user error (a bad option) exits with status 2 through ``report_user_errors``; other outcomes are returned.
    """
    try:
        return command(list(argv))
    except SystemExit as stop:
        return int(stop.code or 0)
