"""The leaderboard's cross-lens matrix: models × test lenses, the training lens marked, in HTML and markdown."""

from __future__ import annotations

from pathlib import Path

from airfisheye_bench.evaluation import build_leaderboard, load_entries, write_results
from airfisheye_bench.evaluation.leaderboard.html import render_html
from airfisheye_bench.evaluation.leaderboard.lens_matrix import SEEN, lens_matrix_html, lens_scores


def _cross_lens(own: float, others: dict[str, float], change: float | None = None) -> dict:
    rows = [{"name": "trained", "seen": True, "metrics": {"rmse": own}, "gap": {"rmse": 0.0}}]
    rows += [
        {"name": name, "seen": False, "metrics": {"rmse": v}, "gap": {"rmse": v / own - 1}}
        for name, v in others.items()
    ]
    block = {"primary_metric": "rmse", "lenses": rows}
    if change is not None:
        block["robustness"] = {"largest_change": {"rmse": change}}
    return block


def _write(root: Path, run: str, rmse: float, cross: dict | None) -> Path:
    return write_results(
        root / run / "results.json",
        task="depth",
        split="test",
        metrics={"rmse": rmse, "abs_rel": 0.3, "delta1": 0.5},
        dataset={"name": "quickstart", "content_sha256": "a" * 64},
        model={"name": "adabins", "encoder": "resnet18", "run_name": run, "checkpoint": f"/{run}/best.ckpt"},
        cross_lens=cross,
    )


def test_matrix_rows_columns_marks_and_colours(tmp_path: Path) -> None:
    files = [
        _write(tmp_path, "one_lens", 14.0, _cross_lens(14.0, {"equisolid 180°": 18.0, "<ds>": 22.0}, 0.4)),
        _write(tmp_path, "many_lenses", 15.0, _cross_lens(15.0, {"equisolid 180°": 15.5})),
        _write(tmp_path, "not_across", 16.0, None),
    ]
    entries, invalid = load_entries(files)
    assert not invalid
    by_run = {e.run: e for e in entries}
    assert [s.name for s in by_run["one_lens"].lenses] == ["trained", "equisolid 180°", "<ds>"]
    assert by_run["one_lens"].lens_robustness == {"rmse": 0.4} and by_run["not_across"].lenses == ()
    board = build_leaderboard(entries, paper=False)

    markdown = board.to_markdown()
    block = markdown[markdown.index("#### Across lenses") :].splitlines()
    assert block[2] == "| model · run | trained | equisolid 180° | <ds> | robustness: largest Δ RMSE (m) |"
    one = next(line for line in block if "one_lens" in line)
    assert f"14.000 {SEEN}" in one and "18.000" in one and "22.000" in one and "0.400" in one
    many = next(line for line in block if "many_lenses" in line)
    assert many == f"| adabins · many_lenses | 15.000 {SEEN} | 15.500 | – | – |"  # not scored there: –
    assert not any("not_across" in line for line in block)

    page = render_html(board)
    matrix = page[
        page.index('class="lens-matrix"') : page.index("</table>", page.index('class="lens-matrix"'))
    ]
    assert "&lt;ds&gt;" in matrix and "<ds>" not in matrix  # names are escaped
    assert matrix.count(f"{SEEN}</td>") == 2 and matrix.count('class="num seen"') == 2
    # Lower RMSE is better: the best cell (14.0) is darkest, the worst (22.0) lightest.
    assert "rgba(10, 95, 163, 0.58)" in matrix and "rgba(10, 95, 163, 0.08)" in matrix
    assert 'title="gap +57.1 % against its own lens(es)"' in matrix


def test_records_without_a_matrix_show_none() -> None:
    assert lens_scores({"metrics": {}}) == ((), {})
    assert lens_matrix_html("rmse", [], "lenses-depth") == ""
