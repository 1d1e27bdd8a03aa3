"""A SLURM job step on this machine: ``python train.py`` as every task of ``nodes x tasks_per_node``, each process
with the environment ``srun`` gives it, so that Lightning's ``SLURMEnvironment`` finds its ranks and the rendezvous
as it does on a cluster.

What the documented command (``python train.py -m hydra/launcher=slurm trainer=ddp trainer.devices=D
trainer.num_nodes=N``, ``configs/hydra/launcher/slurm.yaml``) asks of SLURM is ``--nodes=N --ntasks-per-node=D``,
and ``srun`` starts each task with ``SLURM_NTASKS``, ``SLURM_NNODES``, ``SLURM_NTASKS_PER_NODE``, ``SLURM_NODEID``,
``SLURM_PROCID``, ``SLURM_LOCALID``, ``SLURM_JOB_ID`` and ``SLURM_NODELIST``. From these Lightning derives
``MASTER_ADDR`` (the node list's first host), ``MASTER_PORT`` (15000 + the job id's last four digits), the node
rank and the world size. Here the "nodes" are the loopback addresses ``127.0.0.[1-2]`` of one machine, and the job
id is chosen so that its port is free.

``python -m tests.helpers.cluster RECORD HOOK STEP train.py-overrides...`` is one task: ``train.py`` with two
callbacks added outside its configuration (a resume, which must match the run's configuration, does not inherit
them): :class:`SeenSamples` writes to ``RECORD/rank<r>.jsonl`` what Lightning made of the environment and the sample
ids of every training batch, and, unless ``HOOK`` is ``none``, ``tests.helpers.killer.KillAt`` kills the task.
"""

from __future__ import annotations

import contextlib
import json
import os
import random
import runpy
import signal
import socket
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import lightning as L

from tests.helpers.killer import KillAt

ROOT = Path(__file__).resolve().parents[2]
#: The nodes' addresses, in SLURM's range notation: two loopback addresses of this machine.
NODELIST = "127.0.0.[1-2]"
#: Variables of a launcher or a cluster that the tasks must not inherit from the process that starts them.
_LAUNCH_PREFIXES = ("SLURM_", "TORCHELASTIC_", "PL_", "MASTER_", "GROUP_", "LOCAL_")
_LAUNCH_NAMES = {"WORLD_SIZE", "RANK", "NODE_RANK"}


class SeenSamples(L.Callback):
    """Record, per rank, the environment Lightning resolved and the sample ids of every training batch."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder

    def _write(self, trainer: L.Trainer, entry: dict[str, Any]) -> None:
        self.folder.mkdir(parents=True, exist_ok=True)
        with open(self.folder / f"rank{trainer.global_rank}.jsonl", "a", encoding="utf-8") as f:
            f.write(json.dumps(entry) + "\n")

    def setup(self, trainer: L.Trainer, pl_module: L.LightningModule, stage: str) -> None:
        environment = trainer.strategy.cluster_environment
        self._write(
            trainer,
            {
                "environment": type(environment).__name__,
                "MASTER_ADDR": os.environ.get("MASTER_ADDR"),
                "MASTER_PORT": os.environ.get("MASTER_PORT"),
                "node_rank": trainer.node_rank,
                "global_rank": trainer.global_rank,
                "world_size": trainer.world_size,
                "SLURM_NODEID": os.environ.get("SLURM_NODEID"),
            },
        )

    def on_train_batch_start(
        self, trainer: L.Trainer, pl_module: L.LightningModule, batch: Any, batch_idx: int
    ) -> None:
        self._write(trainer, {"epoch": trainer.current_epoch, "ids": list(batch["sample_id"])})


@dataclass(frozen=True)
class Task:
    """One finished task of a job step."""

    proc_id: int
    returncode: int
    stdout: str
    stderr: str


def free_job_id() -> str:
    """A SLURM job id whose ``MASTER_PORT`` (15000 + its last four digits, Lightning's rule) is free here."""
    for port in random.sample(range(15000, 25000), 200):
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe, contextlib.suppress(OSError):
            probe.bind(("127.0.0.1", port))
            return f"7{port - 15000:04d}"
    raise RuntimeError("no free port in 15000-24999")


def task_environment(job_id: str, nodes: int, tasks_per_node: int, proc_id: int) -> dict[str, str]:
    """The variables ``srun`` sets for task ``proc_id`` of ``sbatch --nodes=nodes --ntasks-per-node=...``."""
    tasks = nodes * tasks_per_node
    return {
        "SLURM_JOB_ID": job_id,
        "SLURM_JOBID": job_id,
        "SLURM_STEP_ID": "0",
        "SLURM_JOB_NAME": "train",
        "SLURM_NTASKS": str(tasks),
        "SLURM_NPROCS": str(tasks),
        "SLURM_NNODES": str(nodes),
        "SLURM_JOB_NUM_NODES": str(nodes),
        "SLURM_NTASKS_PER_NODE": str(tasks_per_node),
        "SLURM_NODELIST": NODELIST,
        "SLURM_JOB_NODELIST": NODELIST,
        "SLURM_NODEID": str(proc_id // tasks_per_node),
        "SLURM_PROCID": str(proc_id),
        "SLURM_LOCALID": str(proc_id % tasks_per_node),
    }


def run_job(
    overrides: list[str],
    record: Path,
    *,
    nodes: int = 2,
    tasks_per_node: int = 1,
    kill: tuple[str, int] | None = None,
    timeout: float = 600,
) -> list[Task]:
    """Start every task of one job step at once (``python -m tests.helpers.cluster``), wait for all of them.

    A task still running after ``timeout`` seconds (a rank waiting for a dead peer) is killed with the others.
    """
    base = {
        k: v for k, v in os.environ.items() if not k.startswith(_LAUNCH_PREFIXES) and k not in _LAUNCH_NAMES
    }
    base["PYTHONPATH"] = os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])
    job_id = free_job_id()
    hook, step = kill if kill is not None else ("none", 0)
    command = [sys.executable, "-m", "tests.helpers.cluster", str(record), hook, str(step), *overrides]
    procs = [
        subprocess.Popen(
            command,
            cwd=ROOT,
            env={**base, **task_environment(job_id, nodes, tasks_per_node, i)},
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            start_new_session=True,
        )
        for i in range(nodes * tasks_per_node)
    ]
    tasks = []
    try:
        for i, proc in enumerate(procs):
            out, err = proc.communicate(timeout=timeout)
            tasks.append(Task(i, proc.returncode, out, err))
    finally:
        for proc in procs:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
    return tasks


def read_record(record: Path) -> dict[int, list[dict[str, Any]]]:
    """Each rank's lines of :class:`SeenSamples`, by global rank."""
    return {
        int(path.stem.removeprefix("rank")): [json.loads(line) for line in path.read_text().splitlines()]
        for path in sorted(record.glob("rank*.jsonl"))
    }


def main(argv: list[str]) -> None:
    record, hook, step, overrides = Path(argv[0]), argv[1], int(argv[2]), argv[3:]
    added: list[L.Callback] = [SeenSamples(record)] + ([KillAt(hook, step)] if hook != "none" else [])
    init = L.Trainer.__init__

    def init_with_callbacks(
        self: L.Trainer, *args: Any, callbacks: list | None = None, **kwargs: Any
    ) -> None:
        init(self, *args, callbacks=[*(callbacks or []), *added], **kwargs)

    L.Trainer.__init__ = init_with_callbacks
    script = ROOT / "train.py"
    sys.argv = [str(script), *overrides]
    runpy.run_path(str(script), run_name="__main__")


if __name__ == "__main__":
    main(sys.argv[1:])
