"""The loader-fed timing waits for the workers' store of prefetched batches to empty before it measures."""

from __future__ import annotations

import time
from collections.abc import Iterator

import torch

from airfisheye_bench.studies.campaign_record import Phase
from airfisheye_bench.studies.train_throughput import fed_steps


class _CountingStep:
    """Stands in for a ``Stepper``: a step that takes no time."""

    device = torch.device("cpu")

    def __call__(self, batch: dict) -> torch.Tensor:
        return batch["image"].sum()


def _loader(stored: int, make_s: float) -> Iterator[dict]:
    """``stored`` batches at once (the workers' store), then one every ``make_s`` seconds."""
    batch, made = {"image": torch.ones(2, 3, 4, 4)}, 0
    while True:
        if made >= stored:
            time.sleep(make_s)
        made += 1
        yield batch


# A made batch takes 50 ms, a stored one none; a wait over 20 ms means the store is empty (margins for a busy CPU).
MAKE_S, EMPTY_MS = 0.05, 20.0


def _phase() -> Phase:
    return Phase("test", time.monotonic() + 60.0)


def test_warm_up_lasts_until_the_store_is_empty() -> None:
    out = fed_steps(
        _CountingStep(), _loader(12, MAKE_S), lambda b: b, 3, 4, _phase(), drain_s=5.0, empty_ms=EMPTY_MS
    )
    # 12 stored batches go in the warm-up, the 13th waits: the store is empty, so the measured steps are made ones.
    assert out["drained"] and out["warmup_steps"] == 13 and out["steps"] == 4
    assert out["host_wait_ms_per_step"] >= 40.0
    assert out["images_per_s"] < 2 / 0.04


def test_a_short_warm_up_measures_the_store() -> None:
    """Without the drain (the campaign's first GPU record), the window reads the store: the rate is unbounded."""
    out = fed_steps(_CountingStep(), _loader(12, MAKE_S), lambda b: b, 3, 4, _phase(), empty_ms=EMPTY_MS)
    assert not out["drained"] and out["warmup_steps"] == 3
    assert out["host_wait_ms_per_step"] < EMPTY_MS


def test_a_loader_that_keeps_up_is_never_drained() -> None:
    out = fed_steps(
        _CountingStep(), _loader(10**9, 0.0), lambda b: b, 2, 3, _phase(), drain_s=0.05, empty_ms=EMPTY_MS
    )
    assert not out["drained"] and out["warmup_s"] >= 0.05 and out["steps"] == 3


def test_the_window_runs_at_least_window_s() -> None:
    out = fed_steps(_CountingStep(), _loader(0, 0.01), lambda b: b, 1, 1, _phase(), window_s=0.1)
    assert out["steps"] > 1 and out["steps"] * out["step_ms"] >= 100.0


def test_the_wait_for_an_empty_store_counts_after_a_slow_minimum_warm_up() -> None:
    """A minimum warm-up longer than ``drain_s`` still leaves it its ``drain_s`` (a loaded CPU, a slow model)."""

    class SlowStep(_CountingStep):
        def __call__(self, batch: dict) -> torch.Tensor:
            time.sleep(0.03)
            return super().__call__(batch)

    out = fed_steps(
        SlowStep(), _loader(3, MAKE_S), lambda b: b, 3, 1, _phase(), drain_s=0.06, empty_ms=EMPTY_MS
    )
    assert out["drained"] and out["warmup_steps"] == 4


def test_no_minimum_warm_up() -> None:
    out = fed_steps(
        _CountingStep(), _loader(0, MAKE_S), lambda b: b, 0, 1, _phase(), drain_s=1.0, empty_ms=EMPTY_MS
    )
    assert out["drained"] and out["warmup_steps"] == 1
