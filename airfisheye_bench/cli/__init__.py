"""The command line: every console script (``airfisheye-train``, ``airfisheye-generate``, ...) and ``--help``.

``airfisheye-train`` and ``airfisheye-evaluate`` are Hydra applications (:mod:`airfisheye_bench.cli.apps`); the
small commands compose their own ``configs/<command>.yaml`` with Hydra's compose API
(:mod:`airfisheye_bench.cli.commands`, :mod:`airfisheye_bench.cli.options`). All of them read ``key=value``
arguments in Hydra's override grammar, answer ``--help`` (``-h``) with their options, and run under
:func:`airfisheye_bench.errors.report_user_errors`: a user error ends in one line, ``error: <message>``, and exit
status 2. The configs come from :func:`airfisheye_bench.constants.config_dir`, so every command works from any
folder, installed from the wheel as well as from a checkout.
"""

from __future__ import annotations

from airfisheye_bench.cli.apps import evaluate, train
from airfisheye_bench.cli.commands import export, generate, inspect, leaderboard, predict, transcode

__all__ = ["evaluate", "export", "generate", "inspect", "leaderboard", "predict", "train", "transcode"]
