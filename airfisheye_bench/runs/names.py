"""Run and sweep folder names: ``${run_name:}`` and ``${sweep_name:}``, the Hydra resolvers of ``hydra.run.dir`` and
``hydra.sweep.dir`` (:func:`register_resolvers`), and the name a run goes by (:func:`run_label`).

Kept light (no torch import): the entry points register the resolvers before Hydra composes.
"""

from __future__ import annotations

import datetime as _dt
import functools
import os
import re
import secrets
import socket
from collections.abc import Mapping
from pathlib import Path

from omegaconf import OmegaConf


@functools.cache
def run_name() -> str:
    """The run directory's name, fixed for the process (``hydra.run.dir`` ends in ``${run_name:}``).

    One command: ``<date>_<time>_<pid>-<4 hex digits>``; two commands started in the same second differ by the
    pid (processes alive at the same time) or the random part (hosts sharing a filesystem). Cached, so every
    re-resolution of the run directory agrees. Lightning's own DDP launcher passes the first process's directory
    to the processes it starts; torchrun and ``srun`` start every rank as its own command, so there the name is
    the one every rank of the launch shares (:func:`launch_id`) after the date.

    Example:
        >>> run_name() == run_name() and f"_{os.getpid()}-" in run_name()
        True
    """
    return run_name_for(os.environ, _dt.datetime.now(), os.getpid(), os.getppid())


def run_name_for(environ: Mapping[str, str], now: _dt.datetime, pid: int, parent_pid: int) -> str:
    """:func:`run_name` for the given environment, time and process ids.

    Example:
        >>> t = _dt.datetime(2026, 11, 24, 9, 30, 5)
        >>> run_name_for({}, t, 812, 1)[:-4]
        '2026-11-24_09-30-05_812-'
        >>> run_name_for({"SLURM_JOB_ID": "4471", "SLURM_STEP_ID": "0", "SLURM_NTASKS": "8"}, t, 812, 1)
        '2026-11-24_slurm-4471.0'
        >>> run_name_for({"TORCHELASTIC_RUN_ID": "none", "WORLD_SIZE": "2"}, t, 812, 77)  # doctest: +ELLIPSIS
        '2026-11-24_torchrun-pid77-...'
    """
    shared = launch_id(environ, parent_pid)
    if shared is not None:  # ranks start seconds apart: the time of day would split them
        return f"{now:%Y-%m-%d}_{shared}"
    return f"{now:%Y-%m-%d_%H-%M-%S}_{pid}-{secrets.token_hex(2)}"


def launch_id(environ: Mapping[str, str], parent_pid: int) -> str | None:
    """The id every rank of one multi-process launch shares, or ``None`` for a single process.

    - ``srun`` with several tasks: ``slurm-<job>.<step>``.
    - torchrun with ``WORLD_SIZE > 1``: ``torchrun-<rendezvous id>`` (``--rdzv-id``; ``--standalone`` draws one);
      with the default id ``none``, the agent's pid, which every rank of a single-node launch shares, and the host
      name: ``torchrun-pid<agent>-<host>``.
    """
    if environ.get("SLURM_JOB_ID") and int(environ.get("SLURM_NTASKS", "1")) > 1:
        step = environ.get("SLURM_STEP_ID")
        return f"slurm-{environ['SLURM_JOB_ID']}" + (f".{step}" if step else "")
    run_id = environ.get("TORCHELASTIC_RUN_ID")
    if run_id is not None and int(environ.get("WORLD_SIZE", "1")) > 1:
        if run_id == "none":
            return f"torchrun-pid{parent_pid}-{socket.gethostname()}"
        return f"torchrun-{_safe(run_id)}"
    return None


def _safe(text: str) -> str:
    """``text`` with anything but letters, digits, ``.``, ``_`` and ``-`` replaced: a folder-name part."""
    return re.sub(r"[^A-Za-z0-9._-]", "_", text)


#: The environment variable that hands a multirun's folder name to jobs that a launcher runs in other processes.
SWEEP_NAME_ENV = "AIRFISHEYE_SWEEP_NAME"


def sweep_name() -> str:
    """The sweep folder's name (``hydra.sweep.dir`` ends in ``${sweep_name:}``): one for every job of a multirun.

    Hydra's basic launcher runs the jobs in the process that resolved the folder, but the submitit launcher
    resolves ``hydra.sweep.dir`` again in each job's own process (another pid, another host): the first resolution
    is kept in :data:`SWEEP_NAME_ENV`, which those processes inherit (locally and through ``sbatch``).

    Example:
        >>> os.environ.pop(SWEEP_NAME_ENV, None) and None
        >>> sweep_name() == run_name() == os.environ.pop(SWEEP_NAME_ENV)
        True
    """
    name = os.environ.get(SWEEP_NAME_ENV)
    if not name:
        name = os.environ[SWEEP_NAME_ENV] = run_name()
    return name


def run_label(run_dir: str | Path) -> str:
    """The name a run goes by (leaderboard rows, MLflow runs): its folder's, with the sweep's for a multirun job.

    A multirun job's folder is its number under the sweep folder (``hydra.sweep.subdir``); a run directory's
    name never is a bare number (:func:`run_name`).

    Example:
        >>> run_label("logs/seg/runs/2026-11-24_09-30-05_812-a3f0")
        '2026-11-24_09-30-05_812-a3f0'
        >>> run_label("logs/seg/multiruns/2026-11-24_09-30-05_812-a3f0/3")
        '2026-11-24_09-30-05_812-a3f0/3'
    """
    path = Path(run_dir)
    return f"{path.parent.name}/{path.name}" if path.name.isdigit() and path.parent.name else path.name


#: A name of :func:`run_name`: ``<date>_<time>_<pid>-<4 hex>``, or ``<date>_<launch id>`` (:func:`launch_id`).
_RUN_NAME = re.compile(
    r"(?P<date>\d{4}-\d{2}-\d{2})_(?:(?P<time>\d{2}-\d{2}-\d{2})_\d+-[0-9a-f]{4}|(?P<launch>(?:slurm|torchrun)-.+))"
)


def run_started(label: str) -> str | None:
    """When a run whose folder :func:`run_name` named started, as a person reads it, from its :func:`run_label`;
    ``None`` for a name given by hand (``hydra.run.dir=``, an evaluation's ``name=``).

    Example:
        >>> run_started("2026-11-24_09-30-05_812-a3f0")
        '2026-11-24 09:30:05'
        >>> run_started("2026-11-24_09-30-05_812-a3f0/3"), run_started("2026-11-24_slurm-4471.0")
        ('2026-11-24 09:30:05, job 3', '2026-11-24 (slurm-4471.0)')
        >>> run_started("adabins-r18") is None
        True
    """
    sweep, _, job = label.rpartition("/")
    name, job = (sweep, job) if sweep and job.isdigit() else (label, "")
    match = _RUN_NAME.fullmatch(name)
    if match is None:
        return None
    time = match["time"]
    when = f"{match['date']} {time.replace('-', ':')}" if time else f"{match['date']} ({match['launch']})"
    return f"{when}, job {job}" if job else when


def register_resolvers() -> None:
    """Register ``${run_name:}`` and ``${sweep_name:}`` (``hydra.run.dir``, ``hydra.sweep.dir``) with OmegaConf;
    safe to call more than once."""
    if not OmegaConf.has_resolver("run_name"):
        OmegaConf.register_new_resolver("run_name", run_name)
    if not OmegaConf.has_resolver("sweep_name"):
        OmegaConf.register_new_resolver("sweep_name", sweep_name)
