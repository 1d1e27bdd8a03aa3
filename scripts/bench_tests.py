"""Time the test suites and measure their coverage of the packages; write the result into ``docs/benchmarks.md``.

``python scripts/bench_tests.py`` runs ``pytest`` (the README's command) and ``pytest -m slow`` one after the other,
each in a fresh process, and records each suite's wall time, its closing line and its slowest tests
(``--suites default``: the default suite only).
``--coverage`` runs both under coverage.py (branch coverage of ``airfisheye_bench``, ``datamodules`` and ``models``,
the subprocesses and pytest-xdist workers included) and adds the combined coverage of the two suites, as the
line-and-branch percentage ``coverage report`` prints. ``--baseline REV`` does the same, in the same run, on a
worktree of ``REV`` (another commit's tests and code, this environment's packages), so the two are measured side by
side on the same machine. The timings are wall times on whatever else the machine runs: run it on an idle machine,
and compare only runs of one invocation.

Writes ``docs/figures/test_suite.json`` (with its provenance) and the section between the ``test-suite`` markers of
``docs/benchmarks.md`` (``--no-docs``: neither).

Example:
    >>> _closing("==== 1577 passed, 22 skipped, 36 warnings in 167.25s (0:02:47) ====")
    '1577 passed, 22 skipped, 36 warnings in 167.25s (0:02:47)'
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from airfisheye_bench.studies.provenance import git_commit, machine

ROOT = Path(__file__).resolve().parents[1]
SUITES = {"default": [], "slow": ["-m", "slow"]}
BEGIN, END = "<!-- test-suite:begin", "<!-- test-suite:end -->"


def _closing(output: str) -> str:
    """pytest's closing line (``N passed, ... in Xs``), without its ``=`` frame."""
    lines = [line.strip("= ") for line in output.splitlines() if re.search(r"\d+ (passed|failed)", line)]
    return lines[-1] if lines else "(no closing line)"


def _slowest(output: str, n: int = 5) -> list[str]:
    """The first ``n`` lines of ``--durations``'s table."""
    lines = output.splitlines()
    start = next((i for i, line in enumerate(lines) if "slowest" in line and "durations" in line), None)
    return (
        [] if start is None else [line.strip() for line in lines[start + 1 : start + 1 + n] if line.strip()]
    )


def _failed(output: str) -> list[str]:
    r"""The tests ``-ra``'s summary lists as failed or in error, so that a record says which.

    >>> _failed("FAILED tests/test_a.py::test_b - assert 1 == 2\nERROR tests/test_c.py::test_d\n1 failed")
    ['tests/test_a.py::test_b', 'tests/test_c.py::test_d']
    """
    return re.findall(r"^(?:FAILED|ERROR) (\S+)", output, flags=re.MULTILINE)


def _coverage_rc(data_file: Path, tree: Path) -> Path:
    rc = data_file.parent / "coveragerc"
    rc.write_text(
        "[run]\nbranch = True\nparallel = True\n"
        f"data_file = {data_file}\nsource_pkgs = airfisheye_bench, datamodules, models\npatch = subprocess, _exit\n"
        f"[report]\ninclude = {tree}/*\n"
    )
    return rc


def run_suites(tree: Path, coverage: bool, scratch: Path, suites: tuple[str, ...] = tuple(SUITES)) -> dict:
    """The ``suites`` in ``tree``: wall time, closing line, slowest tests each; with ``coverage``, the combined
    line-and-branch coverage of the packages over them."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTEST_", "COVERAGE_"))}
    prefix = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-q"]
    if coverage:
        rc = _coverage_rc(scratch / ".coverage", tree)
        env["COVERAGE_RCFILE"] = str(rc)
        prefix = [sys.executable, "-m", "coverage", "run", "-m", "pytest", "-p", "no:cacheprovider", "-q"]
    result: dict = {"tree": str(tree), "suites": {}}
    for name in suites:
        args = SUITES[name]
        load_before = os.getloadavg()  # what else the machine ran: a timing means little without it
        started = time.perf_counter()
        done = subprocess.run([*prefix, *args], cwd=tree, env=env, capture_output=True, text=True)
        wall = time.perf_counter() - started
        load_after = os.getloadavg()
        output = done.stdout + done.stderr
        failed = _failed(output)
        result["suites"][name] = {
            "command": shlex.join(["pytest", *args]),
            "exit_status": done.returncode,
            "wall_s": round(wall, 1),
            # 1-, 5- and 15-minute load averages just before and just after the suite (2 cores: 2.0 is busy)
            "load_before": [round(x, 2) for x in load_before],
            "load_after": [round(x, 2) for x in load_after],
            "closing_line": _closing(output),
            "slowest": _slowest(output),
            "failed": failed,
        }
        print(f"{tree} {name}: {wall:.0f} s, {_closing(output)}", *failed, sep="\n  ", flush=True)
    if coverage:
        cov = [sys.executable, "-m", "coverage"]
        subprocess.run([*cov, "combine", "-q"], cwd=tree, env=env, check=True)
        report = scratch / "coverage.json"
        subprocess.run([*cov, "json", "-q", "-o", str(report)], cwd=tree, env=env, check=True)
        totals = json.loads(report.read_text())["totals"]
        result["coverage"] = {
            "percent": round(totals["percent_covered"], 2),
            "lines": [totals["covered_lines"], totals["num_statements"]],
            "branches": [totals["covered_branches"], totals["num_branches"]],
        }
    return result


def _markdown(record: dict) -> str:
    rows = [
        "| tree | suite | wall | load before → after (1 / 5 / 15 min) | closing line | coverage of the packages (the suites run) |",
        "|---|---|---:|---|---|---|",
    ]
    for label, result in record["trees"].items():
        cov = result.get("coverage")
        cov_text = (
            f"{cov['percent']:.2f}% (lines {cov['lines'][0]}/{cov['lines'][1]}, branches "
            f"{cov['branches'][0]}/{cov['branches'][1]})"
            if cov
            else "not measured"
        )
        for suite in result["suites"].values():
            minutes, seconds = divmod(round(suite["wall_s"]), 60)
            rows.append(
                f"| {label} | `{suite['command']}` | {minutes} min {seconds:02d} s | {_load(suite)} | "
                f"{suite['closing_line']} | {cov_text} |"
            )
    return (
        f"{BEGIN} (generated by scripts/bench_tests.py; do not edit) -->\n"
        f"`{record['command']}` at `{record['commit']}` on {record['machine']}"
        f"{' (under coverage: slower than without)' if record['coverage'] else ''}; "
        "record: [`test_suite.json`](figures/test_suite.json).\n\n" + "\n".join(rows) + f"\n{END}"
    )


def _load(suite: dict) -> str:
    """``0.52 / 0.31 / 0.20 → 1.98 / 1.12 / 0.55``: the load averages around a suite (``-`` in older records).

    >>> _load({"load_before": [0.5, 0.3, 0.2], "load_after": [2.0, 1.1, 0.6]}), _load({})
    ('0.50 / 0.30 / 0.20 → 2.00 / 1.10 / 0.60', '-')
    """
    if "load_before" not in suite:
        return "-"
    return " → ".join(" / ".join(f"{x:.2f}" for x in suite[key]) for key in ("load_before", "load_after"))


def update_docs(doc: Path, section: str) -> None:
    """Replace the generated section of ``doc`` (or append it under a "Test suite" heading)."""
    text = doc.read_text()
    if BEGIN in text:
        start, end = text.index(BEGIN), text.index(END) + len(END)
        text = text[:start] + section + text[end:]
    else:
        text = text.rstrip("\n") + "\n\n## Test suite\n\n" + section + "\n"
    tmp = doc.with_suffix(".md.tmp")
    tmp.write_text(text)
    tmp.replace(doc)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--coverage", action="store_true", help="run both suites under coverage.py")
    parser.add_argument(
        "--baseline", metavar="REV", help="also measure a worktree of this commit, in the same run"
    )
    parser.add_argument(
        "--suites",
        nargs="+",
        choices=list(SUITES),
        default=list(SUITES),
        help="the suites to run (default: both)",
    )
    parser.add_argument("--no-docs", action="store_true", help="print only; write neither JSON nor docs")
    args = parser.parse_args(argv)
    record = {
        "commit": git_commit(ROOT),
        "command": shlex.join(
            ["python", "scripts/bench_tests.py", *(argv if argv is not None else sys.argv[1:])]
        ),
        "machine": machine(),
        "coverage": args.coverage,
        "trees": {},
    }
    with tempfile.TemporaryDirectory(prefix="bench-tests-") as scratch:
        scratch = Path(scratch)
        if args.baseline:
            base = scratch / "baseline"
            subprocess.run(
                ["git", "worktree", "add", "--detach", str(base), args.baseline], cwd=ROOT, check=True
            )
            try:
                (scratch / "b").mkdir()
                record["trees"][f"baseline {args.baseline}"] = run_suites(
                    base, args.coverage, scratch / "b", tuple(args.suites)
                )
            finally:
                subprocess.run(["git", "worktree", "remove", "--force", str(base)], cwd=ROOT, check=False)
        (scratch / "c").mkdir()
        record["trees"]["this tree"] = run_suites(ROOT, args.coverage, scratch / "c", tuple(args.suites))
    print(json.dumps(record, indent=2))
    if not args.no_docs:
        out = ROOT / "docs" / "figures" / "test_suite.json"
        tmp = out.with_suffix(".json.tmp")
        tmp.write_text(json.dumps(record, indent=2) + "\n")
        tmp.replace(out)
        update_docs(ROOT / "docs" / "benchmarks.md", _markdown(record))
    return 0


if __name__ == "__main__":
    sys.exit(main())
