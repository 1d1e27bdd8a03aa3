"""The HTML leaderboard: self-contained, escaped, grouped like the markdown, with a detail view per entry; and
in headless Chromium (when installed): sorting, detail views, no console error and no request leaving the file."""

from __future__ import annotations

import base64
import csv
import hashlib
import io
import re
from html import unescape
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import airfisheye_bench.evaluation.leaderboard as lb
import airfisheye_bench.evaluation.leaderboard.charts as charts
from airfisheye_bench.cli import leaderboard
from airfisheye_bench.evaluation import build_leaderboard, load_entries, write_results
from airfisheye_bench.evaluation.leaderboard import find_results
from airfisheye_bench.evaluation.leaderboard.html import render_html, write_html
from airfisheye_bench.viz import save_png
from tests.helpers.chromium import Page, find_chromium
from tests.helpers.commands import exit_status

HASH_A = "a1b2c3d4" + "0" * 56
HASH_B = "ffee0011" + "1" * 56
EVIL = "<script>alert(1)</script>"
RINGS = ((0, 30), (30, 60), (60, 80), (80, 95))
RANGES = ((0, 10), (10, 20), (20, 40), (40, 80), (80, 120))


def _results(
    root: Path,
    run: str,
    task: str,
    primary: float,
    split: str = "test",
    manifest: str = HASH_A,
    name: str = "",
) -> Path:
    """A results.json as the evaluation writes it in ``root/run``: metrics, ring (and range) breakdown, identity
    (run name ``name`` or ``run``), configuration and four panels."""
    if task == "seg":
        metrics = {"mIoU": primary, "pixel_acc": 0.5 + primary / 2, "IoU/sky": 0.9, "IoU/water": None}
        metrics[f"IoU/{EVIL}"] = primary / 2
        breakdown = {f"ring_{lo}-{hi}/mIoU": primary * (1 - k / 8) for k, (lo, hi) in enumerate(RINGS)}
    else:
        metrics = {"rmse": primary, "abs_rel": primary / 40, "delta1": 0.8}
        breakdown = {f"ring_{lo}-{hi}/rmse": primary * (1 + k / 4) for k, (lo, hi) in enumerate(RINGS)}
        breakdown |= {f"range_{lo}-{hi}/rmse": primary * hi / 40 for lo, hi in RANGES}
    path = write_results(
        root / run / "results.json",
        task,
        split,
        metrics,
        breakdown=breakdown,
        dataset={"root": "/data/synth", "name": "synth", "manifest_sha256": manifest},
        model={
            "source": "onnx" if run.endswith("onnx") else "checkpoint",
            "name": "deeplabv3plus" if task == "seg" else "adabins",
            "run_name": name or run,
            "checkpoint": f"/runs/{run}/last.ckpt",
            "sha256": hashlib.sha256(run.encode()).hexdigest(),
            "config": {"encoder_name": "resnet18"},
        },
        config={"evaluation": {"batch_size": 8, "note": EVIL}, "data": {"root": "/data/synth"}},
    )
    rng = np.random.default_rng(len(run))
    for i in range(4):  # one more than the page shows
        tile = rng.integers(0, 255, (96, 1000, 3), dtype=np.uint8)
        save_png(path.parent / "panels" / f"env_traj_{i:06d}.png", tile)
    return path


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Seg runs (one named like a script tag), depth runs on two splits and a second dataset, one broken file."""
    root = tmp_path_factory.mktemp("runs")
    _results(root, "seg_ckpt", "seg", 0.42)
    _results(root, "seg_onnx", "seg", 0.41)
    _results(root, "evil", "seg", 0.10, name=EVIL)
    _results(root, "depth_test", "depth", 6.0)
    _results(root, "depth_better", "depth", 4.0)
    _results(root, "depth_failed", "depth", float("nan"))  # written as null: no rank, listed last
    _results(root, "depth_val", "depth", 3.0, split="val")
    _results(root, "depth_other_data", "depth", 1.0, manifest=HASH_B)
    (root / "broken").mkdir()
    (root / "broken" / "results.json").write_text('{"version": 1, "task": "seg"}')
    return root


@pytest.fixture(scope="module")
def board(runs: Path) -> lb.Leaderboard:
    entries, problems = load_entries(find_results([runs]))
    return build_leaderboard(entries, paper=True, invalid=problems)


@pytest.fixture(scope="module")
def page(board: lb.Leaderboard) -> str:
    return render_html(board, panels=3, panel_width=400)


class _Tables(HTMLParser):
    """Caption and cell texts of every leaderboard table (``table.board``) of a page."""

    def __init__(self) -> None:
        super().__init__()
        self.tables: list[dict] = []
        self._cell: list[str] | None = None
        self._in_caption = self._in_board = False

    def handle_starttag(self, tag: str, attrs: list) -> None:
        if tag == "table" and ("class", "board") in attrs:
            self.tables.append({"caption": "", "rows": []})
            self._in_board = True
        elif self._in_board and tag == "caption":
            self._in_caption = True
        elif self._in_board and tag == "tr":
            self.tables[-1]["rows"].append([])
        elif self._in_board and tag == "td":
            self._cell = []

    def handle_endtag(self, tag: str) -> None:
        if tag == "table":
            self._in_board = False
        elif tag == "caption":
            self._in_caption = False
        elif tag == "td" and self._cell is not None:
            self.tables[-1]["rows"][-1].append("".join(self._cell).strip())
            self._cell = None

    def handle_data(self, data: str) -> None:
        if self._in_caption:
            self.tables[-1]["caption"] += data
        elif self._cell is not None:
            self._cell.append(data)


def _tables(html: str) -> list[dict]:
    parser = _Tables()
    parser.feed(html)
    return [{"caption": t["caption"], "rows": [r for r in t["rows"] if r]} for t in parser.tables]


# ------------------------------------------------------------------------------------------------ the page


def test_tables_follow_the_leaderboard_groups_and_ranks(board: lb.Leaderboard, page: str) -> None:
    expected = [
        (group.title, [(str(rank or "–"), e.run) for rank, e in group.rows])
        for table in board.tables
        for group in table.groups
    ]
    found = [(t["caption"], [(row[0], row[1]) for row in t["rows"]]) for t in _tables(page)]
    assert found == expected
    depth_titles = [g.title for g in board.tables[1].groups]
    # Each dataset and split is its own table: the val run and the other dataset's run both rank first.
    assert depth_titles[1:] == [
        "synth (manifest a1b2c3d4), test split",
        "synth (manifest a1b2c3d4), val split",
        "synth (manifest ffee0011), test split",
    ]
    assert found[3][1] == [("1", "depth_better"), ("2", "depth_test"), ("–", "depth_failed")]
    assert found[4][1] == [("1", "depth_val")] and found[5][1] == [("1", "depth_other_data")]


def test_rows_show_what_was_evaluated_split_and_every_metric(page: str) -> None:
    seg = _tables(page)[1]
    header = re.search(r'<table class="board" id="table-seg-1">.*?</thead>', page, re.DOTALL)[0]
    labels = re.findall(r"<button type=\"button\">([^<]*)</button>", header)
    assert labels == [
        "rank",
        "run",  # next to the rank, both kept in view when the table scrolls (sticky)
        "model",
        "evaluated",
        "split",
        "mIoU (%)",
        "pixel acc (%)",
        "rim 80-95° mIoU (%)",
    ]
    assert seg["rows"][0] == [
        "1",
        "seg_ckpt",
        "deeplabv3plus / resnet18",
        "checkpoint last",
        "test",
        "42.0",
        "71.0",
        "26.2",
    ]
    assert seg["rows"][1][3] == "ONNX"
    depth = _tables(page)[3]
    assert [row[3:5] for row in depth["rows"]] == [["checkpoint last", "test"]] * 3


def test_paper_rows_are_marked_and_have_no_detail_view(page: str) -> None:
    paper_rows = re.findall(r"<tr class=paper>.*?</tr>", page)
    assert len(paper_rows) == 3
    assert all('<span class="badge">paper</span>' in row and "<a href" not in row for row in paper_rows)
    assert all('<td class="text">paper</td>' in row for row in paper_rows)


def test_every_string_from_results_json_is_escaped(page: str) -> None:
    assert page.count("<script") == 1  # the page's own script, nothing from results.json
    assert EVIL not in page
    # The run name (table, detail view, chart legends), a class name and a configuration value.
    assert page.count("&lt;script&gt;alert(1)&lt;/script&gt;") >= 5


def test_page_is_self_contained(page: str) -> None:
    # Every reference stays inside the file: fragment links or data URIs (SVG namespaces are no requests).
    references = re.findall(r'(?:src|href)="([^"]*)"', page)
    assert references and all(r.startswith(("#", "data:image/jpeg;base64,")) for r in references)
    assert not re.search(r"<link|@import|url\((?!#)", page)
    policy = re.search(r'http-equiv="Content-Security-Policy" content="([^"]*)"', page)[1]
    assert "default-src 'none'" in policy and "img-src data:" in policy
    script = re.search(r"<script>(.*)</script>", page, re.DOTALL)[1]
    digest = base64.b64encode(hashlib.sha256(script.encode()).digest()).decode()
    assert f"script-src 'sha256-{digest}'" in policy  # only this script may run
    ids = re.findall(r'\sid="([^"]+)"', page)
    assert len(ids) == len(set(ids)), "element ids must be unique across the inline charts"


def test_detail_view_has_identity_charts_panels_and_configuration(runs: Path, page: str) -> None:
    entry = re.search(r'<details id="entry-seg-0" class="entry">.*?</div></details>', page, re.DOTALL)[0]
    assert "seg_ckpt" in entry and hashlib.sha256(b"seg_ckpt").hexdigest() in entry and HASH_A in entry
    # Built without runs=: the paths by their last two parts.
    assert "<dd>…/seg_ckpt/results.json</dd>" in entry and "<dd>…/seg_ckpt/last.ckpt</dd>" in entry
    assert 'aria-label="IoU per class, seg_ckpt"' in entry and "n/a" in entry  # water: null
    assert 'aria-label="mIoU (%) by incidence-angle ring, seg_ckpt"' in entry
    assert "depth range" not in entry  # segmentation has no range breakdown
    depth = re.search(r'<details id="entry-depth-0" class="entry">.*?</div></details>', page, re.DOTALL)[0]
    assert "RMSE (m) by depth range" in depth and "RMSE (m) by incidence-angle ring" in depth
    assert "IoU per class" not in depth
    # Three of the four panels, downscaled to the requested width.
    uris = re.findall(r'<img src="data:image/jpeg;base64,([^"]+)"', entry)
    assert len(uris) == 3
    sizes = [Image.open(io.BytesIO(base64.b64decode(u))).size for u in uris]
    assert sizes == [(400, round(96 * 400 / 1000))] * 3
    config = unescape(re.search(r"<pre>(.*?)</pre>", entry, re.DOTALL)[1])
    assert '"batch_size": 8' in config and '"encoder_name": "resnet18"' in config


def test_charts_follow_the_page_colour_and_an_accessible_palette(page: str) -> None:
    svgs = re.findall(r"<svg.*?</svg>", page, re.DOTALL)
    assert len(svgs) >= 6
    for svg in svgs:
        opening = svg[: svg.index(">")]
        assert "viewBox" in opening and " width=" not in opening and 'role="img"' in opening
        colours = {c.upper() for c in re.findall(r"#[0-9a-fA-F]{6}\b", svg)}
        assert colours <= set(charts.OKABE_ITO), colours  # text and axes: currentColor
        assert "currentColor" in svg


def test_a_dollar_in_a_name_is_not_mathtext() -> None:
    svg = charts.bar_chart({"cost $5 $6": 0.5}, metric="IoU", key="k", label="x")
    assert "cost $5 $6" in svg


def test_invalid_files_are_listed_with_their_reason(runs: Path, page: str, board: lb.Leaderboard) -> None:
    items = re.search(r'<section id="invalid">.*?</section>', page, re.DOTALL)[0]
    assert str(runs / "broken" / "results.json") in items and "missing" in items
    assert "## Invalid results.json (not ranked)" in board.to_markdown()


def test_command_writes_the_page(runs: Path, tmp_path: Path, capsys) -> None:
    html = tmp_path / "site" / "board.html"
    args = [f"runs={runs}", f"out={tmp_path / 'board'}", f"html={html}", "skip_invalid=true"]
    assert leaderboard(args) == 0
    assert html.is_file() and "AirFisheye-bench leaderboard" in html.read_text()
    assert str(html) in capsys.readouterr().err
    assert not list(html.parent.glob(".*"))  # written atomically, no temporary left
    # Without skip_invalid the broken file still stops the command, as for the markdown.
    assert leaderboard([f"runs={runs}", f"out={tmp_path / 'b2'}", f"html={tmp_path / 'b2.html'}"]) == 1
    assert not (tmp_path / "b2.html").exists()
    assert exit_status(leaderboard, [f"runs={runs}", "html=board.txt"]) == 2
    assert "html=board.txt: expected an .html file name" in capsys.readouterr().err


def test_paper_only_page_and_missing_or_damaged_panels(tmp_path: Path) -> None:
    path = write_html(build_leaderboard([], paper=True), tmp_path / "paper.html")
    text = path.read_text()
    assert len(_tables(text)) == 3 and '<details id="entry' not in text and 'id="invalid"' not in text
    bare = write_results(tmp_path / "bare" / "results.json", "depth", "test", {"rmse": 2.0})
    entries, _ = load_entries([bare])
    text = render_html(build_leaderboard(entries, paper=False))
    assert 'id="entry-depth-0"' in text and "<img" not in text and "<svg" not in text
    (bare.parent / "panels").mkdir()
    (bare.parent / "panels" / "frame.png").write_bytes(b"not a png")
    text = render_html(build_leaderboard(entries, paper=False))
    assert "unreadable panel" in text and "<img" not in text


# ---------------------------------------------------------------------------------------------- in a browser


CHROMIUM = find_chromium()
needs_browser = pytest.mark.skipif(
    CHROMIUM is None,
    reason="no Chromium on PATH (Debian: apt-get install chromium or chromium-headless-shell; or set "
    "CHROMIUM=/path/to/chrome)",
)


def _column(page: Page, table: str, index: int) -> list[str]:
    return page.evaluate(
        f"Array.from(document.querySelectorAll('#{table} tbody tr')).map(r => r.cells[{index}].textContent)"
    )


@needs_browser
def test_page_in_headless_chromium(board: lb.Leaderboard, tmp_path: Path) -> None:
    html = write_html(board, tmp_path / "leaderboard.html")
    with Page(CHROMIUM) as browser:
        browser.open(html.as_uri())
        assert browser.evaluate("document.title") == "AirFisheye-bench leaderboard"

        # Sorting with the keyboard: mIoU (6th column) best first, then reversed; missing values stay last.
        seg, run_column = "table-seg-1", 1
        assert _column(browser, seg, run_column) == ["seg_ckpt", "seg_onnx", EVIL]
        header = f"#{seg} thead th:nth-child(6)"
        browser.press_enter_on(f"{header} button")
        assert (
            browser.evaluate(f"document.querySelector('{header}').getAttribute('aria-sort')") == "descending"
        )
        assert _column(browser, seg, run_column) == ["seg_ckpt", "seg_onnx", EVIL]
        browser.press_enter_on(f"{header} button")
        assert (
            browser.evaluate(f"document.querySelector('{header}').getAttribute('aria-sort')") == "ascending"
        )
        assert _column(browser, seg, run_column) == [EVIL, "seg_onnx", "seg_ckpt"]
        assert browser.evaluate(f"document.querySelectorAll('#{seg} th[aria-sort]').length") == 1
        # A text column sorts alphabetically.
        browser.press_enter_on(f"#{seg} thead th:nth-child({run_column + 1}) button")
        assert _column(browser, seg, run_column) == sorted(_column(browser, seg, run_column))

        # Lower is better for RMSE (3rd metric column): best first, then reversed; the missing value stays last.
        depth, rmse = "table-depth-1", 7
        assert _column(browser, depth, rmse) == ["4.000", "6.000", "–"]
        browser.press_enter_on(f"#{depth} thead th:nth-child({rmse + 1}) button")
        assert _column(browser, depth, rmse) == ["4.000", "6.000", "–"]
        browser.press_enter_on(f"#{depth} thead th:nth-child({rmse + 1}) button")
        assert _column(browser, depth, rmse) == ["6.000", "4.000", "–"]
        assert browser.evaluate(
            f"document.querySelector('#{depth} thead th:nth-child({rmse + 1})').ariaSort"
        ) == ("descending")

        # A table too wide for its box scrolls sideways with rank and run kept in view.
        offsets = browser.evaluate(
            f"(() => {{ const box = document.querySelector('#{seg}').parentElement; box.style.width = '320px';"
            " box.scrollLeft = 1e6; const row = box.querySelector('tbody tr');"
            " return [box.scrollLeft, row.cells[0].getBoundingClientRect().left - box.getBoundingClientRect().left,"
            " row.cells[1].getBoundingClientRect().left - row.cells[0].getBoundingClientRect().right]; })()"
        )
        assert offsets[0] > 0 and abs(offsets[1]) < 1 and abs(offsets[2]) < 1, offsets
        browser.evaluate(f"document.querySelector('#{seg}').parentElement.style.width = ''")

        # Clicking a model opens its detail view, charts and panels rendered.
        browser.click(f"#{seg} tbody tr:first-child a")
        assert browser.wait_until("document.querySelector('details.entry[open]') !== null")
        opened = browser.evaluate(
            "Array.from(document.querySelectorAll('details.entry[open]')).map(d => d.id)"
        )
        assert opened == ["entry-seg-2"]  # the first row after sorting by run name
        size = browser.evaluate(
            "(() => { const r = document.querySelector('#entry-seg-2 svg').getBoundingClientRect();"
            " return [r.width, r.height]; })()"
        )
        assert size[0] > 100 and size[1] > 50
        assert browser.evaluate(
            "Array.from(document.querySelectorAll('#entry-seg-2 img')).every(i => i.naturalWidth > 0)"
        )
        assert browser.evaluate("document.querySelector('#entry-seg-2 summary').textContent").count(EVIL) == 1

        browser.evaluate("new Promise(r => requestAnimationFrame(() => r(true)))")
        assert browser.console_errors() == []
        leaving = [u for u in browser.requested_urls() if not u.startswith(("file:", "data:"))]
        assert leaving == []
        assert not any(e["method"] == "Page.javascriptDialogOpening" for e in browser.events)


#: A sweep's jobs as the runs folder holds them: a long run name, an Optuna search's overrides, every metric the
#: evaluation writes (the task's headline ones and more), rings and ranges: the widest rows a table gets.
WIDE_METRICS = {
    "depth": ("abs_rel", "sq_rel", "rmse", "rmse_log", "log10", "silog", "delta1", "delta2", "delta3"),
    "completion": ("abs_rel", "rmse", "mae", "irmse", "imae", "delta1", "delta2", "delta3"),
    "seg": ("mIoU", "pixel_acc"),
}
OPTUNA_CHOICES = [
    "task.module.optimizer.lr=0.0072708183450185",
    "task.module.optimizer.weight_decay=0.000123456789",
    "task.module.optimizer.momentum=0.8812345",
    "data.batch_size=8",
    "model.encoder_output_stride=16",
]


@pytest.fixture(scope="module")
def wide_board(tmp_path_factory: pytest.TempPathFactory) -> lb.Leaderboard:
    root = tmp_path_factory.mktemp("wide")
    sweep = "2026-11-24_09-30-05_81234-a3f0"
    evaluated = (
        {
            "source": "checkpoint",
            "stage": "training",
            "checkpoint": "/r/checkpoints/epoch_003.ckpt",
            "tta": "flip",
        },
        {"source": "onnx", "precision": "int8", "onnx": "/r/model.int8.onnx"},
        {"source": "checkpoint", "checkpoint": "/r/checkpoints/epoch_024.ckpt"},
    )
    for task, keys in WIDE_METRICS.items():
        for job, model in enumerate(evaluated):
            run = f"{sweep}/{job + 11}" if job < 2 else "2026-11-25_10-00-00_999-beef"
            write_results(
                root / task / str(job) / "results.json",
                task,
                "test",
                {key: 0.1234567 * (k + 1 + job) for k, key in enumerate(keys)},
                breakdown={
                    f"{kind}_{lo}-{hi}/{keys[0] if task == 'seg' else 'rmse'}": 3.0 + b + job
                    for kind, bins in (("ring", RINGS), ("range", RANGES if task != "seg" else ()))
                    for b, (lo, hi) in enumerate(bins)
                },
                dataset={"name": "airfisheye-synthetic-quickstart", "content_sha256": HASH_A},
                model={
                    **model,
                    "name": {"seg": "deeplabv3plus", "depth": "adabins", "completion": "nlspn"}[task],
                    "run_name": run,
                    "sweep_overrides": OPTUNA_CHOICES if job < 2 else None,
                    "config": {"encoder_name": "resnet50"},
                },
            )
    entries, _ = load_entries(find_results([root]))
    return build_leaderboard(entries, paper=True, root=root)


@needs_browser
def test_the_page_fits_a_1400_px_window_with_legible_charts(
    wide_board: lb.Leaderboard, tmp_path: Path
) -> None:
    """At 1400 px every table shows its last column without scrolling (headers and text cells wrap), and every
    text of every chart (legends, ticks, labels) is at least 12 px; in a narrower box a table still scrolls."""
    html = write_html(wide_board, tmp_path / "wide.html", panels=0)
    with Page(CHROMIUM, width=1400, height=900) as browser:
        browser.open(html.as_uri())
        tables = browser.evaluate(
            "Array.from(document.querySelectorAll('table.board')).map(t => { const box = t.parentElement;"
            " const cells = t.tHead.rows[0].cells; const last = cells[cells.length - 1].getBoundingClientRect();"
            " return [t.id, cells.length, box.scrollWidth - box.clientWidth,"
            " last.right - box.getBoundingClientRect().right, last.right - innerWidth]; })"
        )
        assert (
            len(tables) == 6 and max(columns for _, columns, *_ in tables) == 5 + 9 + 1
        )  # depth: 9 metrics, rim
        for table, _, overflow, past_box, past_window in tables:
            assert overflow <= 0 and past_box <= 0.5 and past_window <= 0, (
                table,
                overflow,
                past_box,
                past_window,
            )
        assert browser.evaluate("document.documentElement.scrollWidth <= innerWidth")

        browser.evaluate("document.querySelectorAll('details.entry').forEach(d => d.open = true)")
        sizes = browser.evaluate(
            "Array.from(document.querySelectorAll('figure.chart svg')).map(svg => [svg.getAttribute('aria-label'),"
            " svg.querySelectorAll('text').length, Math.min(...Array.from(svg.querySelectorAll('text')).map(t => {"
            " const m = t.getScreenCTM(); return parseFloat(getComputedStyle(t).fontSize) * Math.hypot(m.a, m.b); }))])"
        )
        group = [size for label, _, size in sizes if "every entry of this group" in label]
        assert (
            len(group) == 3 and len(sizes) > 3
        )  # one group chart (with a legend) per task, and the detail charts
        assert all(size >= 12 for _, _, size in sizes), [(label, round(size, 1)) for label, _, size in sizes]

        # Not vacuous: the same table in a box too narrow for it overflows, and the box scrolls.
        overflow = browser.evaluate(
            "(() => { const box = document.querySelector('#table-depth-1').parentElement; box.style.width = '800px';"
            " return box.scrollWidth - box.clientWidth; })()"
        )
        assert overflow > 0


@needs_browser
def test_the_browser_checks_catch_a_request_leaving_the_file(board: lb.Leaderboard, tmp_path: Path) -> None:
    """The checks above are not vacuous: an external image is blocked and reported, or seen when unblocked."""
    page = render_html(board, panels=0).replace("</main>", '<img src="http://127.0.0.1:9/x.png"></main>')
    with_policy, without_policy = tmp_path / "with.html", tmp_path / "without.html"
    with_policy.write_text(page)
    without_policy.write_text(re.sub(r'<meta http-equiv="Content-Security-Policy"[^>]*>', "", page))
    with Page(CHROMIUM) as browser:
        browser.open(with_policy.as_uri())
        assert any("Content Security Policy" in e for e in browser.console_errors())
        browser.events.clear()
        browser.open(without_policy.as_uri())
        assert "http://127.0.0.1:9/x.png" in browser.requested_urls()


def test_group_chart_legends_name_each_row_in_full(board: lb.Leaderboard, page: str) -> None:
    """Entries that differ only in what was evaluated get distinct legend entries, none cut short."""
    seg = next(t for t in board.tables if t.task == "seg")
    rows = [e for _, e in seg.groups[1].rows]
    chart = re.search(
        r'<figure class="chart"><svg.*?</figure>', page.split('id="table-seg-1"')[1], re.DOTALL
    )[0]
    texts = unescape(" ".join(re.findall(r"<text[^>]*>(.*?)</text>", chart, re.DOTALL)))
    words = " ".join(texts.split())
    for e in rows:
        assert f"{e.run}: {e.model}, {e.evaluated}" in words or (e.run in words and e.evaluated in words)
    labels = charts.legend_labels([f"{e.run}: {e.model}, {e.evaluated}" for e in rows], width=30)
    assert len(set(labels)) == len(rows)
    assert all(max(len(line) for line in label.splitlines()) <= 30 for label in labels)
    assert ["".join(label.split()) for label in labels] == [
        "".join(f"{e.run}: {e.model}, {e.evaluated}".split()) for e in rows
    ]  # wrapped, never cut


def test_paths_are_shown_relative_to_the_runs_folder(runs: Path, board: lb.Leaderboard) -> None:
    page = render_html(board, panels=0, runs_root=runs)
    entry = re.search(r'<details id="entry-seg-0" class="entry">.*?</div></details>', page, re.DOTALL)[0]
    assert str(runs) not in page
    assert "<dd>seg_ckpt/results.json</dd>" in entry


def test_no_page_or_table_shows_where_the_runs_or_the_data_lie(runs: Path, tmp_path: Path, capsys) -> None:
    """Runs relative to runs=, the dataset by its name and content hash (its folder nowhere, the configuration
    included), in the markdown, the CSV and the HTML page the command writes."""
    html, out = tmp_path / "board.html", tmp_path / "board"
    assert leaderboard([f"runs={runs}", f"out={out}", f"html={html}", "skip_invalid=true"]) == 0
    capsys.readouterr()
    page, md, table = (
        html.read_text(),
        (out / "leaderboard.md").read_text(),
        (out / "leaderboard.csv").read_text(),
    )
    for text in (page, md, table):
        assert str(runs) not in text and "/data/synth" not in text
    entry = re.search(r'<details id="entry-seg-0" class="entry">.*?</div></details>', page, re.DOTALL)[0]
    assert "<dt>dataset</dt><dd>synth (manifest a1b2c3d4)</dd>" in entry and "dataset root" not in entry
    assert f"<dt>manifest sha256</dt><dd>{HASH_A}</dd>" in entry
    config = unescape(re.search(r"<pre>(.*?)</pre>", entry, re.DOTALL)[1])
    assert '"root": "synth (manifest a1b2c3d4)"' in config  # config.data.root: the dataset, by name
    assert "- broken/results.json: " in md and "broken/results.json" in page
    assert {row["path"] for row in csv.DictReader(io.StringIO(table)) if row["run"] == "seg_ckpt"} == {
        "seg_ckpt/results.json"
    }


def test_a_sweep_trial_shows_what_its_sweep_chose_beside_its_name(tmp_path: Path) -> None:
    chosen = ["task.module.optimizer.lr=0.001", f"model.note={EVIL}"]
    path = write_results(
        tmp_path / "sweep" / "2" / "results.json",
        "seg",
        "test",
        {"mIoU": 0.4},
        model={"name": "deeplabv3plus", "run_name": "sweep/2", "sweep_overrides": chosen},
    )
    entries, _ = load_entries([path])
    page = render_html(build_leaderboard(entries, paper=False))
    (row,) = _tables(page)[0]["rows"]
    assert (
        row[1] == "sweep/2optimizer.lr=0.001 model.note=" + EVIL
    )  # the name, the overrides below it, shortened
    assert (
        '<code title="task.module.optimizer.lr=0.001">optimizer.lr=0.001</code>' in page
    )  # in full on hover
    summary = re.search(r"<summary>(.*?)</summary>", page)[1]
    assert "sweep/2 (task.module.optimizer.lr=0.001 model.note=&lt;script&gt;" in summary
    assert "<dt>sweep overrides</dt>" in page and EVIL not in page
