"""Sharded generation: any number of shards writes the one-machine dataset; a killed shard run again finishes it; a
finished shard is not redone; the merge names what is missing."""

from __future__ import annotations

import contextlib
import io
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from airfisheye_bench.cli import generate as cli_main
from airfisheye_bench.io.content import content_identity
from airfisheye_bench.io.manifest import verify
from airfisheye_bench.synth import shards, writer
from airfisheye_bench.synth.presets import get_preset, plan_trajectories
from airfisheye_bench.synth.scene import ENVIRONMENTS
from tests.helpers.commands import ROOT, Outcome, assert_one_line_error, exit_status

#: ``airfisheye-generate`` of the tiny preset into ``out``, one shard of three (``progress=false``).
TINY = ["preset=tiny", "progress=false"]


def _shard(out: Path, shard: int | str, count: int = 3, *more: str) -> int:
    return cli_main([*TINY, f"out={out}", f"shards={count}", f"shard={shard}", *more])


def _identity(root: Path) -> str:
    return str(content_identity(root, use_cache=False)["content_sha256"])


def _run(*argv: str) -> Outcome:
    """``airfisheye-generate preset=tiny progress=false <argv>`` in this process, its output captured."""
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        code = exit_status(cli_main, [*TINY, *argv])
    return Outcome(code, stdout.getvalue(), stderr.getvalue())


# ---------------------------------------------------------------------------------------------- the split
@pytest.mark.parametrize("preset", ["tiny", "quickstart", "paper"])
def test_each_trajectory_is_in_one_shard_and_the_shards_are_balanced(preset: str) -> None:
    plans = plan_trajectories(get_preset(preset), ENVIRONMENTS)
    longest = max(p.num_frames for p in plans)
    for count in range(1, len(plans) + 1):
        split = shards.shard_trajectories(plans, count)
        assert sorted(t for members in split for t in members) == list(range(len(plans)))
        assert all(members for members in split) and split == shards.shard_trajectories(plans, count)
        loads = [sum(plans[t].num_frames for t in members) for members in split]
        assert max(loads) - min(loads) <= longest, (count, loads)


# ------------------------------------------------------------------------------------------ the identity
@pytest.mark.integration
@pytest.mark.parametrize("count", [1, 3])
def test_any_number_of_shards_writes_the_one_machine_dataset(
    count: int, tiny_dataset: Path, tmp_path
) -> None:
    out = tmp_path / "sharded"
    order = list(reversed(range(count)))  # the last shard first: the order the jobs run in does not matter
    for i, shard in enumerate(order):
        assert _shard(out, shard, count) == 0
        assert (out / "manifest.json").is_file() == (i == count - 1)  # the shard that completes it merges it
    assert _identity(out) == _identity(tiny_dataset)
    assert (out / "manifest.json").read_bytes() == (tiny_dataset / "manifest.json").read_bytes()
    assert not list(out.glob(".airfisheye-journal*")) and not (out / writer.STATE_NAME).exists()
    assert verify(out).ok


@pytest.mark.integration
def test_a_finished_shard_is_not_redone(tiny_dataset: Path, tmp_path, monkeypatch) -> None:
    out = tmp_path / "sharded"
    first = shards.generate_shard("tiny", out, shard=1, shards=3, progress=False)
    assert first.rendered == 2 and first.missing == {"suburban/traj00": 9, "town/traj00": 3}

    def refuse(self, job):
        raise AssertionError(f"{job} was rendered again")

    monkeypatch.setattr(writer.Worker, "run", refuse)
    again = shards.generate_shard("tiny", out, shard=1, shards=3, progress=False)
    assert again.rendered == 0 and again.missing == first.missing
    assert "finished before" in again.summary(plan_trajectories(get_preset("tiny"), ENVIRONMENTS))
    monkeypatch.undo()
    for shard in (0, 2):
        shards.generate_shard("tiny", out, shard=shard, shards=3, progress=False)
    monkeypatch.setattr(writer.Worker, "run", refuse)
    done = shards.generate_shard("tiny", out, shard=0, shards=3, progress=False)  # the dataset is complete
    assert done.complete and done.rendered == 0
    assert writer.generate_dataset("tiny", out, progress=False) == out  # and is the whole run's
    assert _identity(out) == _identity(tiny_dataset)


#: ``airfisheye-generate <argv>``, killed (SIGKILL) at its ``argv[1]``-th file write, half-way through it: the
#: temporary file written, not yet renamed into place.
_KILLED_AT_A_WRITE = """
import os, signal, sys
from airfisheye_bench import atomic
from airfisheye_bench.cli import generate
writes, original = 0, atomic.atomic_write
def dying(path, write):
    global writes
    writes += 1
    if writes == int(sys.argv[1]):
        write(path.with_name(f".{path.name}.0123456789ab.tmp"))
        os.kill(os.getpid(), signal.SIGKILL)
    original(path, write)
atomic.atomic_write = dying
sys.exit(generate(sys.argv[2:]))
"""


@pytest.mark.integration
def test_a_shard_killed_half_way_and_run_again_gives_the_same_dataset(tiny_dataset: Path, tmp_path) -> None:
    out = tmp_path / "sharded"
    assert _shard(out, 1) == 0  # another shard's trajectory, finished
    # Debris of a shard still writing (or killed) in its own folder: not the business of shard 0's start.
    theirs = out / "modular_houses" / "traj00" / ".000001.png.fedcba987654.tmp"
    theirs.write_bytes(b"being written")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    argv = [*TINY, f"out={out}", "shards=3", "shard=0"]
    # Shard 0 (8 frames of ~20 files each, after its trajectory's 4 metadata files) dies inside its fourth frame.
    killed = subprocess.run(
        [sys.executable, "-c", _KILLED_AT_A_WRITE, "70", *argv],
        cwd=ROOT,
        env=env,
        capture_output=True,
        timeout=300,
    )
    assert killed.returncode == -9, killed.stderr[-2000:]
    journal = out / shards.shard_journal(0, 3)
    assert 1 < len(journal.read_text().splitlines()) < 9 and not (out / "manifest.json").exists()
    ours = list((out / "suburban").rglob("*.tmp"))
    assert ours, "the kill left no temporary file"
    # A file of the killed frame written whole but never journaled is replaced, whatever it holds.
    journaled = {json.loads(line)["unit"] for line in journal.read_text().splitlines()}
    frame = next(f for f in range(8) if f"0:{f}" not in journaled)
    unjournaled = sorted((out / "suburban").rglob(f"{frame:06d}.*"))
    assert unjournaled, "the killed frame left no file renamed into place"
    unjournaled[0].write_bytes(b"garbage")

    report = shards.generate_shard("tiny", out, shard=0, shards=3, progress=False)
    assert 0 < report.rendered < 8 and report.missing == {"town/traj00": 3}
    assert not any(p.exists() for p in ours) and theirs.exists()
    theirs.unlink()  # (its shard would replace it when run again)
    assert _shard(out, 2) == 0
    assert _identity(out) == _identity(tiny_dataset) and verify(out).ok


# --------------------------------------------------------------------------------------- what is refused
@pytest.mark.integration
def test_the_merge_names_the_shard_to_run_again(tmp_path) -> None:
    out = tmp_path / "sharded"
    assert _shard(out, 0) == 0 and _shard(out, 2) == 0
    error = assert_one_line_error(_run(f"out={out}", "shards=3", "shard=merge"), "shard 1 of 3", "shard=1")
    assert "modular_houses/traj00 (3)" in error and not (out / "manifest.json").exists()
    assert _shard(out, 1) == 0 and (out / "manifest.json").is_file()
    merged = _run(f"out={out}", "shards=3", "shard=merge")  # complete: nothing left but to say so
    assert merged.returncode == 0 and f"content: {_identity(out)}" in merged.stdout


@pytest.mark.parametrize(
    ("argv", "names"),
    [
        (["shards=4", "shard=0"], ["shards=4", "1 to 3"]),
        (["shards=3", "shard=3"], ["shard=3", "0 to 2"]),
        (["shards=3"], ["shards=3", "shard=0 .. shard=2"]),
        (["shards=3", "shard=last"], ["shard=last", "merge"]),
        (["shards=3", "shard=true"], ["shard=True"]),
    ],
)
def test_a_bad_shard_option_is_one_line_naming_it(argv: list[str], names: list[str], tmp_path) -> None:
    assert_one_line_error(_run(f"out={tmp_path / 'out'}", *argv), *names)
    assert not (tmp_path / "out").exists()


def test_shards_need_an_output_folder() -> None:
    assert_one_line_error(_run("shards=3", "shard=0"), "out=DIR")


#: ``airfisheye-generate <argv>`` as its console script runs it.
_GENERATE = "import sys; from airfisheye_bench.cli import generate; sys.exit(generate(sys.argv[1:]))"


@pytest.mark.slow
def test_three_shards_started_together_write_the_one_machine_quickstart_sample(tmp_path) -> None:
    """The quick-start preset sampled to one frame per flight (16 flights, 4 environments), its three shards started
    at once as three processes: they race to create the folder and its state file, and to merge."""
    sample = ["preset=quickstart", "total_frames=16", "progress=false"]
    one, sharded = tmp_path / "one", tmp_path / "sharded"
    assert cli_main([*sample, f"out={one}"]) == 0
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    jobs = [
        subprocess.Popen(
            [sys.executable, "-c", _GENERATE, *sample, f"out={sharded}", "shards=3", f"shard={i}"],
            cwd=ROOT,
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for i in range(3)
    ]
    outputs = [job.communicate(timeout=600) for job in jobs]
    assert [job.returncode for job in jobs] == [0, 0, 0], [err[-2000:] for _, err in outputs]
    assert any("the dataset is complete" in out for out, _ in outputs)
    assert _identity(sharded) == _identity(one)
    assert (sharded / "manifest.json").read_bytes() == (one / "manifest.json").read_bytes()
