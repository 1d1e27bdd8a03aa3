"""The leaderboard: every task's ranked table (:func:`build_leaderboard`), rendered as markdown and CSV."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from airfisheye_bench.atomic import atomic_write_text
from airfisheye_bench.evaluation.leaderboard.collect import LeaderboardEntry, paper_baselines
from airfisheye_bench.evaluation.leaderboard.paths import ShownPaths
from airfisheye_bench.evaluation.leaderboard.rank import TaskTable, task_table
from airfisheye_bench.evaluation.leaderboard.text import render_csv, render_markdown
from airfisheye_bench.specs import all_tasks

__all__ = ["Leaderboard", "build_leaderboard"]


@dataclass(frozen=True)
class Leaderboard:
    """All task tables; render with :meth:`to_markdown` / :meth:`to_csv`, save with :meth:`write`.

    Attributes:
        tables: One per task that has rows, in the order seg, depth, completion.
        files: Number of ``results.json`` rows (paper rows not counted).
        paper: Whether the paper's baselines are included.
        invalid: ``"<path>: <reason>"`` of each ``results.json`` that failed validation (not ranked).
        root: The folder the results were collected from (``runs=``): the renderings show the paths under it
            relative to it (:meth:`shown_paths`).
    """

    tables: tuple[TaskTable, ...]
    files: int = 0
    paper: bool = True
    invalid: tuple[str, ...] = ()
    root: str | None = None

    def shown_paths(self, root: str | Path | None = None) -> ShownPaths:
        """How the renderings show a path: relative to ``root`` (default :attr:`root`) when under it."""
        return ShownPaths(self.root if root is None else root)

    def to_markdown(self) -> str:
        """The leaderboard as markdown: one section per task, one table per dataset and split.

        Example:
            >>> print(build_leaderboard([], paper=True).to_markdown())  # doctest: +ELLIPSIS
            # AirFisheye-bench leaderboard
            ...
            | 1 | DeepLabV3+ / ResNet50 | paper | paper (released AirFisheye) | test | – | 51.2 | – | paper IV-A |
            ...
        """
        shown = self.shown_paths()
        return render_markdown(self.tables, self.files, self.paper, [shown.text(p) for p in self.invalid])

    def to_csv(self) -> str:
        """Wide CSV, one row per result, a ``task`` column and raw values (fractions, metres, empty = missing); its
        ``path`` is the ``results.json``, relative to :attr:`root` when under it.

        Example:
            >>> print(build_leaderboard([], paper=True).to_csv().splitlines()[1])  # doctest: +ELLIPSIS
            seg,1,DeepLabV3+ / ResNet50,paper,paper (released AirFisheye),test,,AirFisheye (released),,,paper IV-A,,mIoU,0.512,...
        """
        return render_csv(self.tables, self.shown_paths())

    def write(self, out_dir: str | Path) -> tuple[Path, Path]:
        """Write ``leaderboard.md`` and ``leaderboard.csv`` atomically into ``out_dir`` (created if needed).

        Example:
            >>> import tempfile
            >>> md, table = build_leaderboard([]).write(tempfile.mkdtemp())
            >>> md.name, table.name
            ('leaderboard.md', 'leaderboard.csv')
        """
        out_dir = Path(out_dir)
        md, table = out_dir / "leaderboard.md", out_dir / "leaderboard.csv"
        atomic_write_text(md, self.to_markdown())
        atomic_write_text(table, self.to_csv())
        return md, table


def build_leaderboard(
    entries: Iterable[LeaderboardEntry],
    paper: bool = True,
    invalid: Sequence[str] = (),
    root: str | Path | None = None,
) -> Leaderboard:
    """Rank rows per task, within groups of the same dataset and split.

    Args:
        entries: Rows, e.g. from :func:`collect_results`.
        paper: Add :func:`paper_baselines` (in their own group: the real dataset's test split).
        invalid: ``"<path>: <reason>"`` of the files that failed validation (:func:`load_entries`); the
            renderings list them under the tables rather than dropping them silently.
        root: The folder the results were collected from: paths under it are shown relative to it.

    Returns:
        The leaderboard; tasks without any row are left out.

    Example:
        >>> mine = LeaderboardEntry("seg", "test", "deeplabv3plus / resnet18", "run1", "tiny",
        ...                         metrics={"mIoU": 0.3})
        >>> board = build_leaderboard([mine], paper=True)
        >>> [[(r, e.run) for r, e in g.rows] for g in board.tables[0].groups]
        [[(1, 'paper IV-A')], [(1, 'run1')]]
    """
    rows = list(entries) + (list(paper_baselines()) if paper else [])
    tables = tuple(
        task_table(spec.name, [e for e in rows if e.task == spec.name])
        for spec in all_tasks()
        if any(e.task == spec.name for e in rows)
    )
    return Leaderboard(
        tables=tables,
        files=sum(not e.paper for e in rows),
        paper=paper,
        invalid=tuple(invalid),
        root=str(root) if root is not None else None,
    )
