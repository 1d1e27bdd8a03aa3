"""The commands run as a user runs them: in a subprocess (where a real process is the point: exit codes of the
interpreter, environment read at import, console handlers, imports) or in this process through the same entry
function, with its output captured and its exit status taken from ``SystemExit`` (seconds cheaper: no fresh
interpreter importing torch, Lightning, Hydra and the model zoo)."""

from __future__ import annotations

import contextlib
import io
import logging
import os
import subprocess
import sys
import traceback
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

from airfisheye_bench.errors import EXIT_USER_ERROR

ROOT = Path(__file__).resolve().parents[2]
TRAIN = "train.py"
EVALUATE = "scripts/evaluate.py"
EXPORT = "scripts/export_onnx.py"
PREDICT = "scripts/predict.py"
INSPECT = "-c"  # python -c "<the console entry point>" key=value ...
INSPECT_ENTRY = "from airfisheye_bench.cli.commands import inspect; inspect()"


@dataclass(frozen=True)
class Outcome:
    returncode: int
    stdout: str
    stderr: str


def run_command(
    script: str, args: list[str], debug: bool = False, extra_env: dict[str, str] | None = None
) -> Outcome:
    """Run ``python <script> <args>`` from the project root as a user would (``HYDRA_FULL_ERROR`` unset)."""
    env = {k: v for k, v in os.environ.items() if k != "HYDRA_FULL_ERROR"}
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    env.update(extra_env or {})
    if debug:
        env["HYDRA_FULL_ERROR"] = "1"
    done = subprocess.run(
        [sys.executable, script, *args], cwd=ROOT, env=env, capture_output=True, text=True, timeout=300
    )
    return Outcome(done.returncode, done.stdout, done.stderr)


def _entry(script: str, args: list[str]) -> tuple[Callable[[], object], list[str]]:
    """The function a script runs and the ``argv`` it reads."""
    from airfisheye_bench.cli import apps, commands

    if script == TRAIN:
        return apps.train, args
    if script == EVALUATE:
        return apps.evaluate, args
    if script == EXPORT:  # scripts/export_onnx.py: sys.exit(export())
        return lambda: sys.exit(commands.export(args)), args
    if script == PREDICT:  # scripts/predict.py: sys.exit(predict())
        return lambda: sys.exit(commands.predict(args)), args
    if script == INSPECT and args and args[0] == INSPECT_ENTRY:  # its return value is dropped, as by ``-c``
        return lambda: commands.inspect(args[1:]), args[1:]
    raise ValueError(f"no in-process entry for {script} {args[:1]}")


@contextlib.contextmanager
def _isolated_process_state(argv: list[str], env: dict[str, str]) -> Iterator[None]:
    """``sys.argv``, the environment, the root logger and Hydra's global state as a fresh process has them, put
    back afterwards (Hydra configures logging and a global instance per run)."""
    from hydra.core.global_hydra import GlobalHydra

    saved_argv, saved_env = sys.argv, dict(os.environ)
    root = logging.getLogger()
    saved_handlers, saved_level = list(root.handlers), root.level
    sys.argv = argv
    os.environ.pop("HYDRA_FULL_ERROR", None)
    os.environ.update(env)
    GlobalHydra.instance().clear()
    try:
        yield
    finally:
        GlobalHydra.instance().clear()
        for handler in root.handlers:
            if handler not in saved_handlers:
                root.removeHandler(handler)
                handler.close()
        for handler in saved_handlers:
            if handler not in root.handlers:
                root.addHandler(handler)
        root.setLevel(saved_level)
        sys.argv = saved_argv
        os.environ.clear()
        os.environ.update(saved_env)


def run_in_process(script: str, args: list[str], extra_env: dict[str, str] | None = None) -> Outcome:
    """:func:`run_command` without the subprocess: the script's entry function, ``argv`` as the script would
    see it, stdout and stderr captured, the exit status from ``SystemExit`` (an uncaught exception: its traceback
    on stderr and status 1, as the interpreter does). For behaviours that do not need a fresh process: the
    environment of ``extra_env`` must not be one that a library reads when it is imported."""
    function, argv = _entry(script, args)
    out, err = io.StringIO(), io.StringIO()
    code = 0
    with (
        _isolated_process_state([script, *argv], extra_env or {}),
        contextlib.redirect_stdout(out),
        contextlib.redirect_stderr(err),
    ):
        try:
            function()
        except SystemExit as stop:
            code = stop.code if isinstance(stop.code, int) else (0 if stop.code is None else 1)
            if isinstance(stop.code, str):
                print(stop.code, file=sys.stderr)
        except Exception:  # a bug: the traceback, as the interpreter prints it
            traceback.print_exc()
            code = 1
    return Outcome(code, out.getvalue(), err.getvalue())


def assert_one_line_error(outcome: Outcome, *names: str) -> str:
    """Exit status 2, no traceback, and exactly one ``error:`` line naming every one of ``names``."""
    output = outcome.stdout + outcome.stderr
    errors = [line for line in outcome.stderr.splitlines() if line.startswith("error: ")]
    assert outcome.returncode == EXIT_USER_ERROR, output[-3000:]
    assert "Traceback" not in output, output[-3000:]
    assert len(errors) == 1, outcome.stderr[-3000:]
    for name in names:
        assert name in errors[0], errors[0]
    return errors[0]


def exit_status(command: Callable[[Sequence[str]], int], argv: Sequence[str]) -> int:
    """``command(argv)``'s exit status: its return value, or the code of the ``SystemExit`` it raised.

    A user error (a bad option) exits with status 2 through ``report_user_errors``; other outcomes are returned.
    """
    try:
        return command(list(argv))
    except SystemExit as stop:
        return int(stop.code or 0)
