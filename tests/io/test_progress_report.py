"""Progress of long file work where the console is not a terminal (captured here, as a redirected one): a log
line at every tenth, no bar frames."""

from __future__ import annotations

import logging

import pytest

from airfisheye_bench.io.progress_report import ProgressReport, track


def test_a_redirected_report_logs_a_line_per_tenth_and_draws_no_bar(
    caplog: pytest.LogCaptureFixture, capsys: pytest.CaptureFixture[str]
) -> None:
    with caplog.at_level(logging.INFO), ProgressReport(1000, "generate tiny", "frame") as report:
        for _ in range(1000):
            report.update()
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 10 and lines[-1].startswith("generate tiny 1000/1000 frames: frames/s ")
    assert lines[0].startswith("generate tiny 100/1000 frames")
    captured = capsys.readouterr()
    assert captured.out == captured.err == ""  # no tqdm frame


def test_a_resumed_report_starts_at_the_work_done(caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.INFO), ProgressReport(20, "generate tiny", "frame", initial=15) as report:
        report.update(5)
    assert [r.getMessage().split(":")[0] for r in caplog.records] == ["generate tiny 20/20 frames"]


def test_track_yields_every_item_and_is_silent_when_disabled(caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.INFO):
        assert list(track(range(7), 7, "verify", "file", enabled=False)) == list(range(7))
        assert not caplog.records
        assert list(track(range(7), 7, "verify", "file")) == list(range(7))
    assert len(caplog.records) == 7  # fewer than ten units: a line for each
