"""Sharded generation: ``N`` processes (an array of cluster jobs, or commands on one machine) each write whole
trajectories of one dataset folder, and the last one to finish writes its index.

A preset's trajectories are shared out once, by :func:`shard_trajectories`: whole trajectories (a shard builds each
scene once and owns its folders), balanced by frame count. Shard ``i`` writes its trajectories into the common
``out`` folder as :func:`~airfisheye_bench.synth.writer.generate_dataset` would, journaling each finished unit in a
journal of its own (``.airfisheye-journal.shard-<i>-of-<N>.jsonl``), so that:

* a frame's files are the same bytes whatever the number of shards (a frame depends on its trajectory and index
  only): the merged dataset, its ``manifest.json`` and its content identity are the one-machine run's;
* a shard killed half-way and run again redoes only its units that no journal holds (a file written but not
  journaled is written again), and a finished shard run again renders nothing;
* once every unit of every trajectory is journaled, by any shard, the dataset is finished
  (:func:`~airfisheye_bench.synth.writer.merge_journals`: split files, ``dataset.yaml``, ``manifest.json``): by the
  shard that completes it, or by :func:`merge_shards` (``shard=merge``). Two shards finishing together both write
  the same files, each atomically.

The shards need one folder they all see (a cluster's shared file system); they never write the same file, and each
removes the debris of an interrupted write in its own trajectories' folders only.

Example:
    >>> from airfisheye_bench.synth.presets import get_preset, plan_trajectories
    >>> from airfisheye_bench.synth.scene import ENVIRONMENTS
    >>> plans = plan_trajectories(get_preset("quickstart"), ENVIRONMENTS)
    >>> [sum(plans[t].num_frames for t in shard) for shard in shard_trajectories(plans, 3)]
    [321, 329, 374]
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

from airfisheye_bench.atomic import remove_stale_temporaries
from airfisheye_bench.errors import ConfigError
from airfisheye_bench.synth.dataset_yaml import generator_identity
from airfisheye_bench.synth.presets import SynthConfig, TrajectoryPlan, plan_trajectories
from airfisheye_bench.synth.scene import ENVIRONMENTS
from airfisheye_bench.synth.writer import as_config, merge_journals, open_output, write_trajectories

log = logging.getLogger(__name__)

__all__ = [
    "ShardReport",
    "check_shards",
    "generate_shard",
    "merge_shards",
    "shard_journal",
    "shard_trajectories",
]


@dataclass(frozen=True)
class ShardReport:
    """What :func:`generate_shard` did.

    Attributes:
        root: The dataset folder.
        shard: This shard's index, ``0 <= shard < shards``.
        shards: The number of shards.
        trajectories: This shard's trajectories (``<env>/<trajectory>``).
        frames: Their frames.
        rendered: Frames rendered by this call (0: the shard had finished before, or the dataset had).
        missing: Trajectories of the dataset still missing units (metadata or frames), with how many; empty: the
            dataset is complete (merged by this call or before).
    """

    root: Path
    shard: int
    shards: int
    trajectories: tuple[str, ...]
    frames: int
    rendered: int
    missing: dict[str, int]

    @property
    def complete(self) -> bool:
        return not self.missing

    def summary(self, plans: list[TrajectoryPlan]) -> str:
        """One line: what the shard wrote and whether the dataset is complete (or which shards it waits for)."""
        done = f"{self.rendered} rendered now" if self.rendered else "finished before: none rendered now"
        head = f"shard {self.shard} of {self.shards}: {', '.join(self.trajectories)}, {self.frames} frames ({done})"
        if self.complete:
            return f"{head}; the dataset is complete"
        return f"{head}; waiting for {waiting_for(self.missing, plans, self.shards)}"


def shard_trajectories(plans: list[TrajectoryPlan], shards: int) -> list[list[int]]:
    """The trajectories (indices into ``plans``) of each of ``shards`` shards, each shard's in plan order.

    Whole trajectories, balanced by frames: the longest first, each to the shard with the fewest frames so far (the
    lowest index among equals). It depends on the plans and ``shards`` only, so every job of an array computes the
    same split.

    Raises:
        ConfigError: ``shards`` is below 1 or above the number of trajectories.
    """
    if not 1 <= shards <= len(plans):
        raise ConfigError(
            f"shards={shards}: expected 1 to {len(plans)}, the preset's trajectories (a shard writes whole "
            "trajectories; workers= spreads one shard over a machine's cores)"
        )
    load = [0] * shards
    members: list[list[int]] = [[] for _ in range(shards)]
    for t in sorted(range(len(plans)), key=lambda t: (-plans[t].num_frames, t)):
        target = min(range(shards), key=lambda s: (load[s], s))
        load[target] += plans[t].num_frames
        members[target].append(t)
    return [sorted(m) for m in members]


def check_shards(shard: int, shards: int, plans: list[TrajectoryPlan]) -> None:
    """Refuse a shard index outside ``0..shards-1`` or a ``shards`` the preset cannot be split into.

    Raises:
        ConfigError: naming ``shard=`` or ``shards=``.
    """
    shard_trajectories(plans, shards)
    if not 0 <= shard < shards:
        raise ConfigError(f"shard={shard}: expected 0 to {shards - 1} (shards={shards}), or shard=merge")


def shard_journal(shard: int, shards: int) -> str:
    """The journal file name of shard ``shard`` of ``shards``."""
    return f".airfisheye-journal.shard-{shard}-of-{shards}.jsonl"


def generate_shard(
    config: SynthConfig | str,
    out_dir: str | Path,
    shard: int,
    shards: int,
    seed: int = 0,
    workers: int = 1,
    device: str = "cpu",
    progress: bool = True,
) -> ShardReport:
    """Write shard ``shard`` of ``shards`` of a dataset into ``out_dir``, then finish the dataset if no unit of any
    trajectory is missing any more.

    Args:
        config: A :class:`SynthConfig` or a preset name; every shard must be given the same (and the same seed).
        out_dir: The folder every shard writes into.
        shard: This shard, ``0 <= shard < shards``.
        shards: The number of shards, at most the preset's trajectories.
        seed: Base seed.
        workers: Processes rendering this shard's frames.
        device: Torch device for ray casting.
        progress: Report progress.

    Raises:
        ConfigError: A bad ``shard`` or ``shards``, or ``out_dir`` holding another dataset or unrelated files.

    Example:
        >>> report = generate_shard("tiny", "/tmp/afb-tiny-shards", shard=0, shards=3)   # doctest: +SKIP
        >>> report.trajectories, report.complete                                         # doctest: +SKIP
        (('suburban/traj00',), False)
    """
    config = as_config(config)
    if int(workers) < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    plans = plan_trajectories(config, ENVIRONMENTS)
    check_shards(shard, shards, plans)
    mine = shard_trajectories(plans, shards)[shard]
    root = Path(out_dir)
    report = ShardReport(
        root, shard, shards, tuple(plans[t].key for t in mine), sum(plans[t].num_frames for t in mine), 0, {}
    )
    if open_output(root, generator_identity(config, seed)):
        log.info("%s is already complete", root)
        return report
    for t in mine:  # the other shards may be writing theirs
        remove_stale_temporaries(root / plans[t].key)
    label = f"{config.name} (shard {shard} of {shards})"
    journal = root / shard_journal(shard, shards)
    rendered = write_trajectories(
        root, (config, seed, plans), mine, journal, int(workers), device, progress, label
    )
    missing = merge_journals(root, config, seed, plans)
    return ShardReport(root, shard, shards, report.trajectories, report.frames, rendered, missing)


def merge_shards(
    config: SynthConfig | str, out_dir: str | Path, seed: int = 0, shards: int | None = None
) -> Path:
    """Finish a dataset whose shards have all been written (``shard=merge``); a complete one is left as it is.

    Args:
        config: The shards' config or preset name.
        out_dir: The shards' folder.
        seed: The shards' seed.
        shards: The number of shards they were run with, to name the unfinished ones (``None``: trajectories only).

    Raises:
        ConfigError: A trajectory is missing units (the message names it and its shard), or ``out_dir`` holds
            another dataset or no dataset being generated.
    """
    config = as_config(config)
    root = Path(out_dir)
    plans = plan_trajectories(config, ENVIRONMENTS)
    if shards is not None:
        shard_trajectories(plans, shards)
    if not root.is_dir():
        raise ConfigError(f"out={root}: no such folder; run the shards first (shard=0 .. shard=N-1)")
    if open_output(root, generator_identity(config, seed)):
        return root
    missing = merge_journals(root, config, seed, plans)
    if missing:
        raise ConfigError(f"out={root} is not complete: waiting for {waiting_for(missing, plans, shards)}")
    return root


def waiting_for(missing: dict[str, int], plans: list[TrajectoryPlan], shards: int | None) -> str:
    """What is missing, in words: the shards to run (again) and the units (a trajectory's metadata, each frame) that
    no journal holds yet.

    Example:
        >>> from airfisheye_bench.synth.presets import get_preset, plan_trajectories
        >>> plans = plan_trajectories(get_preset("tiny"), ENVIRONMENTS)
        >>> print(waiting_for({"town/traj00": 3}, plans, 3))
        shard 2 of 3 (start shard=2 unless it is running): 3 of 15 units (a trajectory's metadata, each frame) missing, in town/traj00 (3)
    """
    total = sum(p.num_frames + 1 for p in plans)
    where = ", ".join(f"{key} ({count})" for key, count in missing.items())
    units = (
        f"{sum(missing.values())} of {total} units (a trajectory's metadata, each frame) missing, in {where}"
    )
    if not shards:
        return units
    owner = {plans[t].key: s for s, members in enumerate(shard_trajectories(plans, shards)) for t in members}
    which = sorted({owner[key] for key in missing})
    if len(which) == 1:
        return f"shard {which[0]} of {shards} (start shard={which[0]} unless it is running): {units}"
    listed = ", ".join(map(str, which[:-1])) + f" and {which[-1]}"
    starts = ", ".join(f"shard={s}" for s in which)
    return f"shards {listed} of {shards} (start each of {starts} that is not running): {units}"
