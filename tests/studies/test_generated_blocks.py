"""Generated blocks of the Markdown reports (:mod:`airfisheye_bench.studies.generated_blocks`)."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

import pytest

from airfisheye_bench.studies import evaluation_speed, lightning_overhead
from airfisheye_bench.studies.generated_blocks import write_block

BEGIN, END = "<!-- t:begin -->", "<!-- t:end -->"


def test_write_block_inserts_the_section_then_rewrites_only_its_block(tmp_path: Path) -> None:
    """The first write adds the section before the given heading; later ones rewrite the block alone, so the
    record's citation and the judgement written under it stay."""
    doc = tmp_path / "benchmarks.md"
    doc.write_text("# Benchmarks\n\n## Metrics\n\nm\n\n## Models\n\nx\n")
    write_block(doc, "first", BEGIN, END, section="## Speed", before="## Models")
    doc.write_text(doc.read_text().replace(f"{END}\n", f"{END}\n\nRecord: r. Judged: j.\n"))
    write_block(doc, "second", BEGIN, END, section="## Speed", before="## Models")
    assert doc.read_text() == (
        f"# Benchmarks\n\n## Metrics\n\nm\n\n## Speed\n\n{BEGIN}\nsecond\n{END}\n\n"
        "Record: r. Judged: j.\n\n## Models\n\nx\n"
    )


def test_write_block_appends_the_section_without_the_heading_it_goes_before(tmp_path: Path) -> None:
    doc = tmp_path / "benchmarks.md"
    doc.write_text("# Benchmarks\n")
    write_block(doc, "table", BEGIN, END, section="## Speed", before="## Models")
    assert doc.read_text() == f"# Benchmarks\n\n## Speed\n\n{BEGIN}\ntable\n{END}\n"


@pytest.mark.parametrize("module", [evaluation_speed, lightning_overhead], ids=lambda m: m.__name__)
def test_the_benchmarks_doc_holds_the_block_of_each_write_docs(module: ModuleType) -> None:
    """``--write-docs`` finds its block in docs/benchmarks.md, inside its section (else it adds a second one)."""
    text = module.DOCS.read_text(encoding="utf-8")
    assert text.count(module.BEGIN) == 1 and text.count(module.END) == 1
    assert text.index(module.SECTION) < text.index(module.BEGIN) < text.index(module.END)
