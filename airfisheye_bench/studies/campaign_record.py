"""The record of a time-boxed benchmark campaign: one JSON file, rewritten atomically after every measurement.

A campaign runs phases one after the other against a wall-clock budget (:class:`CampaignRecord`). Each phase has
its own time box: its loops stop at the phase's deadline (:meth:`Phase.expired`), a signal ``grace_s`` later
interrupts a phase stuck in Python code (:class:`PhaseTimeout`), and a phase that fails records its error while the
next one starts. A watchdog thread writes the record and ends the process once the whole budget and twice the
grace are spent (a phase stuck in C code). Whatever happens, the file holds every measurement finished before, and
``status`` says how the campaign ended: ``running`` (killed from outside), ``complete``, ``partial`` (a phase
skipped, stopped, timed out or failed) or ``killed by the watchdog``.

Example:
    >>> import json, tempfile, pathlib
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "run.json"
    >>> record = CampaignRecord(path, budget_s=60, data={"tasks": {}}, watchdog=False)
    >>> record.run_phase("one", lambda phase: record.set("tasks", "seg", value={"images_per_s": 1.5}), budget_s=5)
    >>> record.finish()
    >>> saved = json.loads(path.read_text())
    >>> saved["status"], saved["phases"]["one"]["status"], saved["tasks"]["seg"]["images_per_s"]
    ('complete', 'ok', 1.5)
"""

from __future__ import annotations

import json
import math
import os
import signal
import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from airfisheye_bench.atomic import atomic_write_text


class PhaseTimeout(Exception):
    """A phase ran past its time box and its grace."""


@dataclass
class Phase:
    """A running phase: its deadline (``time.monotonic``) and whether a loop stopped early at it."""

    name: str
    deadline: float
    stopped: list[str] = field(default_factory=list)

    def left(self) -> float:
        return self.deadline - time.monotonic()

    def expired(self, what: str = "") -> bool:
        """Whether the time box is spent; records ``what`` was cut short."""
        if self.left() > 0:
            return False
        if what and what not in self.stopped:
            self.stopped.append(what)
        return True


def _alarm(signum: int, frame: Any) -> None:
    raise PhaseTimeout("the phase ran past its time box")


class CampaignRecord:
    """The campaign's JSON document and its clock.

    Args:
        path: The JSON file (its folder is created).
        budget_s: Wall-clock seconds for the whole campaign, from now.
        data: The document's initial contents (``status``, ``phases``, ``budget_s`` and ``elapsed_s`` are added).
        grace_s: How long past a deadline before a phase is interrupted (and the process, past the budget).
        watchdog: Start the thread that ends the process past the budget (tests of this class leave it off).
    """

    def __init__(
        self,
        path: str | Path,
        budget_s: float,
        data: dict[str, Any],
        grace_s: float = 15.0,
        watchdog: bool = True,
    ) -> None:
        self.path = Path(path)
        self.start = time.monotonic()
        self.deadline = self.start + budget_s
        self.grace_s = grace_s
        self.data = {"status": "running", "budget_s": budget_s, "elapsed_s": 0.0, **data, "phases": {}}
        self._lock = threading.RLock()
        self._ended = threading.Event()  # set by finish(): the watchdog stands down
        self.save()
        if watchdog:
            threading.Thread(target=self._watch, name="campaign-watchdog", daemon=True).start()

    def left(self) -> float:
        """Seconds left of the whole budget."""
        return self.deadline - time.monotonic()

    def save(self) -> None:
        """Rewrite the file (atomically: a reader or a kill never sees half of it)."""
        with self._lock:
            self.data["elapsed_s"] = round(time.monotonic() - self.start, 2)
            atomic_write_text(self.path, json.dumps(_plain(self.data), indent=1) + "\n")

    def set(self, *keys: str, value: Any) -> None:
        """``data[k1][k2]... = value`` (missing levels created), then save."""
        with self._lock:
            node = self.data
            for key in keys[:-1]:
                node = node.setdefault(key, {})
            node[keys[-1]] = value
            self.save()

    def run_phase(
        self, name: str, run: Callable[[Phase], Any], budget_s: float, minimum_s: float = 5.0
    ) -> Any:
        """Run ``run(phase)`` in a time box of ``budget_s`` (less if the campaign has less left); its result.

        Skipped when fewer than ``minimum_s`` are left. An error or a timeout is recorded, not raised (a
        ``KeyboardInterrupt`` is raised).
        """
        left = self.left()
        entry: dict[str, Any] = {"budget_s": round(min(budget_s, max(left, 0.0)), 1)}
        if left < minimum_s:
            entry["status"] = f"skipped: {left:.0f} s left, the phase needs {minimum_s:.0f} s"
            self.set("phases", name, value=entry)
            return None
        phase = Phase(name, time.monotonic() + min(budget_s, left))
        entry["status"] = "running"
        self.set("phases", name, value=entry)
        # The interrupt is SIGUSR1 from a timer thread, not SIGALRM: an outer alarm (pytest-timeout's) stays armed.
        alarm = None
        if threading.current_thread() is threading.main_thread():
            previous = signal.signal(signal.SIGUSR1, _alarm)
            main = threading.main_thread().ident
            alarm = threading.Timer(
                max(phase.left(), 0.0) + self.grace_s, signal.pthread_kill, (main, signal.SIGUSR1)
            )
            alarm.daemon = True
            alarm.start()
        started, result = time.monotonic(), None
        try:
            result = run(phase)
            entry["status"] = (
                "ok" if not phase.stopped else "stopped at the time box: " + ", ".join(phase.stopped)
            )
        except PhaseTimeout:
            entry["status"] = "timeout"
        except Exception as err:  # one phase's failure is recorded; the next phase still runs
            entry["status"] = "error"
            entry["error"] = f"{type(err).__name__}: {err}"
            entry["traceback"] = traceback.format_exc().splitlines()[-12:]
        finally:
            if alarm is not None:
                alarm.cancel()
                signal.signal(signal.SIGUSR1, previous)
            entry["wall_s"] = round(time.monotonic() - started, 2)
            self.set("phases", name, value=entry)
        return result

    def skip(self, name: str, reason: str) -> None:
        """Record that phase ``name`` did not run, and why."""
        self.set("phases", name, value={"status": f"skipped: {reason}"})

    def finish(self) -> None:
        """Mark the campaign ended: ``complete`` if every phase ran to its end, else ``partial``."""
        phases = self.data["phases"].values()
        self.set("status", value="complete" if all(p["status"] == "ok" for p in phases) else "partial")
        self.stand_down()

    def stand_down(self) -> None:
        """Stop the watchdog (the campaign ended, or failed with an exception its caller will see)."""
        self._ended.set()

    def _watch(self) -> None:
        # A campaign that ended in time (finish()) lets its process live: main() also runs inside a test process.
        if self._ended.wait(max(self.left(), 0.0) + 2 * self.grace_s):
            return
        with self._lock:
            self.data["status"] = "killed by the watchdog: over the budget"
            self.save()
        os._exit(124)


def _plain(value: Any) -> Any:
    """JSON-ready: NaN and infinity as ``null``, tuples as lists."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    return value


__all__ = ["CampaignRecord", "Phase", "PhaseTimeout"]
