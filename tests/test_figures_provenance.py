"""Every result file under ``docs/figures/`` names where it comes from: a full, clean commit and the command that
wrote it, at its top level or under ``provenance`` (``docs/results.md`` cites numbers only from such files), and the
identity of the data it read: a dataset's content SHA-256 (``dataset``, ``datasets`` or ``content_sha256``), or a
real file's SHA-256 (``scan``). And every table of measurements in ``docs/`` cites such a file (below)."""

from __future__ import annotations

import glob
import json
import re
from dataclasses import dataclass
from pathlib import Path

import pytest

from airfisheye_bench.studies.bench_record import tables as bench_tables

ROOT = Path(__file__).resolve().parents[1]
FIGURES = sorted((ROOT / "docs" / "figures").rglob("*.json"))
_FULL_COMMIT = re.compile(r"[0-9a-f]{40}")
_SHA256 = re.compile(r"[0-9a-f]{64}")
_IDENTITY_KEYS = {"dataset", "datasets", "content_sha256", "scan"}

#: The figures that read no data files, and what they measure instead.
READS_NO_DATA = {
    "test_suite.json": "the test suites' wall times",
    "test_suite_coverage.json": "the test suites' wall times and coverage",
    "occlusion_memory.json": "occlusion methods' memory on a scene built in memory from its name and seed",
    # Speed benchmarks kept through scripts/bench_record.py: the data they time are made by the script itself.
    "generator_presets.json": "the frame writer's time per frame of the presets it renders",
    "synth.json": "the renderer's rays per second on scenes built from their names and seeds",
    "metrics.json": "the metrics' update time on random tensors",
    "tartanair.json": "the loader's time per sample on the miniature TartanAir root and tiny preset it writes",
    "kitti360.json": "the loader's time per sample on the miniature KITTI-360 root it writes",
    "evaluate.json": "the evaluation loop over prediction files it writes from the tiny preset's frames",
    "models.json": "the paper recipes' models on random tensors (parameters, forward time, ONNX parity)",
    "camera_input_steps.json": "model steps on random tensors and a lens's ray map computed from its model",
    "remap.json": "the cube-to-fisheye tables and remaps, ours and cv2's, on random faces of a seeded generator",
    "remap_erp.json": "the panorama's and the cube's tables and remaps on random images of a seeded generator",
    "remap_models.json": "each camera model's ray grid, table and remap: committed calibrations, random faces",
    "lidar.json": "the occlusion methods' time and accuracy on a LiDAR scan of a scene built from its seed",
    "lidar_scans.json": "the occlusion methods on scan variants (seeded) of the structured scene built in memory",
    "lidar_scans_boxes.json": "the occlusion methods on scan variants (seeded) of the analytic boxes scene",
    "lidar_rings.json": "scan organisation and ordering, today's and an earlier commit's, on a scene built in memory",
    "lightning.json": "train steps, Trainer against a plain loop, on a random batch served from memory",
    "lightning_malloc.json": "the same train steps with glibc's malloc thresholds set, on a random batch from memory",
}

#: Records of data generated inside the run on a lent GPU machine before the run hashed what it generated; each names
#: how the data were made instead. The code hashes it since (``gpu_campaign.generate_data``, ``bench_cpu_contention``).
GENERATED_NOT_HASHED = {
    "campaign_nvidia-h200_b076001.json": "data.generator: the generator's command line",
    "campaign_nvidia-h200.json": "data.generator: the generator's command line",
    "contention_seg.json": "data: the tiny preset",
    "contention_depth.json": "data: the tiny preset",
}


@pytest.mark.parametrize("path", FIGURES, ids=lambda p: str(p.relative_to(ROOT / "docs" / "figures")))
def test_a_figure_names_a_clean_full_commit_and_its_command(path: Path) -> None:
    data = json.loads(path.read_text())
    source = data if "commit" in data else data.get("provenance", {})
    commit, command = source.get("commit"), source.get("command")
    assert isinstance(commit, str) and _FULL_COMMIT.fullmatch(commit), f"{path}: commit {commit!r}"
    assert isinstance(command, str) and "python " in command, f"{path}: command {command!r}"


def _identities(node: object, under_identity_key: bool = False) -> set[str]:
    """Every SHA-256 held (at any depth) under one of :data:`_IDENTITY_KEYS`."""
    if isinstance(node, dict):
        return set().union(
            *(_identities(v, under_identity_key or k in _IDENTITY_KEYS) for k, v in node.items())
        )
    if isinstance(node, list):
        return set().union(*(_identities(v, under_identity_key) for v in node))
    return {node} if under_identity_key and isinstance(node, str) and _SHA256.fullmatch(node) else set()


@pytest.mark.parametrize(
    "path",
    [p for p in FIGURES if p.name not in READS_NO_DATA | GENERATED_NOT_HASHED.keys()],
    ids=lambda p: str(p.relative_to(ROOT / "docs" / "figures")),
)
def test_a_figure_names_the_data_it_read(path: Path) -> None:
    assert _identities(json.loads(path.read_text())), (
        f"{path}: no dataset content SHA-256 (or real file SHA-256) under {sorted(_IDENTITY_KEYS)}"
    )


def test_the_figures_said_to_read_no_data_exist() -> None:
    """An exemption outlives no file: each name of :data:`READS_NO_DATA` is a figure here."""
    assert set(READS_NO_DATA) <= {p.name for p in FIGURES}


@pytest.mark.parametrize("name", sorted(GENERATED_NOT_HASHED))
def test_a_record_of_unhashed_data_says_how_they_were_made(name: str) -> None:
    (path,) = [p for p in FIGURES if p.name == name]
    data = json.loads(path.read_text())["data"]
    made = data["generator"] if isinstance(data, dict) else data
    assert "preset=tiny" in made or "tiny preset" in made, f"{path}: {made!r}"


def test_the_identity_finder() -> None:
    digest = "a" * 64
    assert _identities({"dataset": {"root": "/x", "content_sha256": digest}}) == {digest}
    assert _identities({"datasets": [digest]}) == {digest}
    assert _identities({"results": [{"sha256": digest}]}) == set()  # a file checksum outside an identity key
    assert _identities({"dataset": {"name": "tiny"}}) == set()


def test_there_are_figures() -> None:
    assert len(FIGURES) > 10


# ---------------------------------------------------------------------------------------------------------------
# A record behind every table of measurements in docs/.
#
# A table of measurements is a markdown table under docs/ whose body holds a measured-looking number: one with a
# decimal point (0.112, 15.45 ms, 2.20 %) or a count with thousands separators (68,692). It cites its record when a
# committed JSON under docs/ is named (linked or quoted, resolved against docs/, the repository or docs/figures/) in
# the paragraph just before it, in it, in the paragraph just after it, or in the begin marker of the generated block
# it sits in. Tables whose numbers are definitions, not measurements, are listed in DEFINITIONS, each with why;
# tables of measurements that no record backs yet are listed in NOT_YET_REMEASURED, each with why: they are
# expected to fail (strict), so the gap shows in every run and a table that gains its record must leave the list.

DOCS = sorted((ROOT / "docs").glob("*.md"))
_NUMBER = re.compile(r"(?<![\w.])\d+\.\d+(?![\w.])|(?<![\w.,])\d{1,3}(?:,\d{3})+(?![\w,])")
_RECORD = re.compile(r"[\w./*\[\]-]+\.json")
_SEPARATOR = re.compile(r"^\|[\s:|-]+\|$")
_GENERATED = re.compile(r"<!-- [\w-]+:begin \(generated .*?\) -->")
_MARKER = re.compile(r"<!-- [\w-]+:(begin|end)\b.*-->")


@dataclass(frozen=True)
class Table:
    """A markdown table of a doc: where it is, its header and body, and the text a citation may sit in."""

    doc: str
    line: int
    header: str
    body: tuple[str, ...]
    context: str

    @property
    def key(self) -> str:
        """``<doc>: | <first three header cells> |``: how the lists below name it."""
        cells = [c.strip() for c in self.header.replace("\\|", "/").strip().strip("|").split("|")]
        return f"{self.doc}: | {' | '.join(cells[:3])} |"

    def measures(self) -> bool:
        return any(_NUMBER.search(row) for row in self.body)

    def records(self) -> list[Path]:
        """The committed JSON files under docs/ that the table's context names."""
        found: set[Path] = set()
        for name in dict.fromkeys(_RECORD.findall(self.context)):
            for base in (ROOT / "docs", ROOT, ROOT / "docs" / "figures"):
                found |= {Path(p) for p in glob.glob(str(base / name)) if Path(p).is_file()}
        return sorted(p for p in found if ROOT / "docs" in p.resolve().parents)


def _paragraph(lines: list[str], start: int, step: int) -> list[str]:
    """The text lines of the paragraph from ``start`` going ``step`` (blank lines and a generated block's markers
    first skipped; a heading ends it)."""
    i, out = start, []
    while 0 <= i < len(lines) and (not lines[i].strip() or _MARKER.fullmatch(lines[i].strip())):
        i += step
    while 0 <= i < len(lines) and lines[i].strip() and not lines[i].startswith("#"):
        out.append(lines[i])
        i += step
    return [line for line in out[::step] if not line.strip().startswith("|")]


def tables_of(doc: str, text: str) -> list[Table]:
    """Every markdown table of ``text`` (a header row followed by a ``|---|`` row)."""
    lines, found, begin, i = text.splitlines(), [], "", 0
    while i < len(lines):
        line = lines[i].strip()
        if _GENERATED.search(line):
            begin = line
        elif line.startswith("<!--") and line.endswith(":end -->"):
            begin = ""
        if line.startswith("|") and i + 1 < len(lines) and _SEPARATOR.match(lines[i + 1].strip()):
            end = i + 2
            while end < len(lines) and lines[end].strip().startswith("|"):
                end += 1
            around = [begin, *_paragraph(lines, i - 1, -1), *lines[i:end], *_paragraph(lines, end, 1)]
            found.append(Table(doc, i + 1, line, tuple(lines[i + 2 : end]), "\n".join(around)))
            i = end
        else:
            i += 1
    return found


MEASUREMENT_TABLES = [
    t for p in DOCS for t in tables_of(p.name, p.read_text(encoding="utf-8")) if t.measures()
]

#: Tables whose numbers state what something is (a default, a convention, a datasheet, a published figure), not
#: what was measured here.
DEFINITIONS = {
    "evaluation.md: | model | input (H x W, channels) | normalisation |": (
        "published models' input conventions, read from their repositories (normalisation constants, sizes)"
    ),
    "datasets.md: | key | default | what it is |": "the data options' declared defaults (data_options.py)",
    "datasets.md: | data | seg | depth |": "what each public dataset provides, its licence and where to get it",
    "design.md: | model | parameters | maps |": "the camera models' parameters and conventions",
    "design.md: |  | pixel coordinate | angle |": "the panorama's pixel-to-angle convention",
    "design.md: | preset | channels | points / rev. |": "the LiDAR presets' datasheet values",
    "design.md: | format | layout | frame / rings |": "the scan file formats",
    "design.md: | method | what it does | options (default) |": "the occlusion methods and their default options",
    "design.md: | file (under `<env>/Data_easy/Data_hard/P000/`) | encoding | what the source serves |": (
        "TartanAir's file encodings"
    ),
    "design.md: | split | lens | jitter |": "the lens draws a config sets per split",
    "design.md: | format | recognised by | lens models it gives |": "the calibration file formats read",
    "design.md: | key | formula |": "the depth metrics' definitions",
    "design.md: | key | formula | unit |": "the completion metrics' definitions",
    "design.md: | task | model | source |": "the paper's published baselines, quoted from its tables (the paper is "
    "their record)",
    "design.md: | task | recipe (paper) | as configured |": "the paper recipes' settings",
    "design.md: | unit | holds | why it sits there |": "the layers of the package",
    "training.md: | recipe | from the paper | chosen here (the paper leaves it open) |": "the recipes' choices "
    "(learning rates, schedules): settings, not results",
    "results.md: |  | quickstart | occlusion |": "the two synthetic rigs' configurations (presets.py)",
}

#: Tables of measurements that no committed record backs yet, each with why: a strict xfail until it gains one (a run
#: of its script through ``python scripts/bench_record.py --json docs/figures/bench/<name>.json -- scripts/<bench>.py
#: ...``) and leaves this list. Empty: every table of measurements in docs/ cites its record.
NOT_YET_REMEASURED: dict[str, str] = {}


def _expectation(table: Table) -> object:
    reason = NOT_YET_REMEASURED.get(table.key)
    marks = [pytest.mark.xfail(strict=True, reason=f"not yet re-measured: {reason}")] if reason else []
    return pytest.param(table, id=f"{table.doc}:{table.line}", marks=marks)


@pytest.mark.parametrize("table", [_expectation(t) for t in MEASUREMENT_TABLES if t.key not in DEFINITIONS])
def test_a_table_of_measurements_cites_its_record(table: Table) -> None:
    assert table.records(), (
        f"docs/{table.doc}:{table.line} {table.key}: a table of measurements with no committed record named "
        "before, in or under it (docs/figures/...json); cite it, or list the table with why"
    )


@pytest.mark.parametrize(
    "table",
    [t for t in MEASUREMENT_TABLES if any("output" in json.loads(p.read_text()) for p in t.records())],
    ids=lambda t: f"{t.doc}:{t.line}",
)
def test_a_table_citing_a_benchmark_record_is_that_records_output(table: Table) -> None:
    """A benchmark's record keeps what the script printed: the table in the docs is one of its tables."""
    printed = [
        [_cells(row) for row in rows]
        for path in table.records()
        for rows in bench_tables(json.loads(path.read_text()).get("output", ""))
    ]
    shown = [_cells(table.header), *(_cells(row) for row in table.body)]
    assert any(shown == [printed_rows[0], *printed_rows[2:]] for printed_rows in printed), (
        f"docs/{table.doc}:{table.line}: not a table its record printed ({[str(p) for p in table.records()]})"
    )


def _cells(row: str) -> list[str]:
    return [c.strip() for c in row.strip().strip("|").split("|")]


def test_each_listed_table_is_in_the_docs() -> None:
    """An exemption outlives no table: each key of the lists names a table of measurements in docs/."""
    keys = {t.key for t in MEASUREMENT_TABLES}
    assert not (set(DEFINITIONS) | set(NOT_YET_REMEASURED)) - keys
    assert not set(DEFINITIONS) & set(NOT_YET_REMEASURED)


def test_the_table_finder_tells_a_cited_measurement_from_an_uncited_one() -> None:
    text = "\n".join(
        [
            "Measured ([`occlusion_memory.json`](figures/occlusion_memory.json)):",
            "",
            "| size | ms |",
            "|---|---:|",
            "| 512 | 1.25 |",
            "",
            "Nothing cited here.",
            "",
            "| size | ms |",
            "|---|---:|",
            "| 512 | 68,692 |",
            "",
            "| key | default |",
            "|---|---|",
            "| batch_size | 8 |",
        ]
    )
    cited, uncited, definition = tables_of("x.md", text)
    assert cited.measures() and [p.name for p in cited.records()] == ["occlusion_memory.json"]
    assert uncited.measures() and not uncited.records() and uncited.line == 9
    assert not definition.measures()  # whole numbers alone: a setting, not a measurement
    assert cited.key == "x.md: | size | ms |"
