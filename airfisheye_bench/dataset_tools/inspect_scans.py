"""``airfisheye-inspect`` on LiDAR scan files: what each scan holds, where its rings come from, what is removed.

For a folder of scans (or one scan file) rather than a dataset root: every file :func:`~airfisheye_bench.io.scan.
load_scan` reads is checked, its rings are resolved (the file's field, its firing order, or the channel table of
``lidar``) and the returns the datamodule would remove are counted (near the sensor, no channel explains them,
empty cells of an organised cloud). A file that cannot be read is a problem naming it.

Example:
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> np.array([[10.0, 0.0, -1.7, 0.3], [0.2, 0.1, 0.0, 0.0]], dtype=np.float32).tofile(folder / "0.bin")
    >>> report = inspect_scans(folder, lidar="hdl64e")
    >>> report.ok, report.scans[0].near_origin
    (True, 1)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from airfisheye_bench.geometry.lidar import LidarSpec
from airfisheye_bench.geometry.rings import resolve_rings
from airfisheye_bench.geometry.scan_filter import DEFAULT_MIN_RANGE, filter_scan
from airfisheye_bench.io.errors import DatasetFormatError
from airfisheye_bench.io.lidar_spec import load_lidar_spec
from airfisheye_bench.io.scan import load_scan, scan_format


@dataclass
class ScanSummary:
    """One scan file as the datamodule would serve it (``rings`` is ``None`` without a field and a spec)."""

    path: Path
    format: str
    points: int
    ring_source: str | None
    per_ring: np.ndarray | None  # kept returns per ring [N_C]
    near_origin: int
    unexplained: int
    no_returns: int

    def line(self) -> str:
        rings = "rings: none (no ring field; give lidar=<preset or spec file> to estimate them)"
        if self.per_ring is not None:
            counts = self.per_ring
            rings = (
                f"rings from {self.ring_source}: {int((counts > 0).sum())}/{len(counts)} with returns, "
                f"{int(counts.min())}-{int(np.median(counts))}-{int(counts.max())} (min-median-max) per ring"
            )
        return (
            f"{self.path.name} ({self.format}): {self.points} returns; {rings}; removed {self.near_origin} "
            f"within min_range, {self.unexplained} no channel explains, {self.no_returns} empty cells"
        )


@dataclass
class ScanReport:
    """What :func:`inspect_scans` found: one summary per readable file, and the problems."""

    root: Path
    spec: LidarSpec | None
    scans: list[ScanSummary] = field(default_factory=list)
    problems: list[tuple[str, str]] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.problems

    def summary(self, limit: int = 20) -> str:
        total = sum(s.points for s in self.scans)
        removed = [
            sum(getattr(s, k) for s in self.scans) for k in ("near_origin", "unexplained", "no_returns")
        ]
        sensor = self.spec.name or "custom spec" if self.spec is not None else "no LiDAR spec"
        lines = [
            f"{self.root}: {len(self.scans)} scans ({sensor}), {total} returns; removed {removed[0]} within "
            f"min_range, {removed[1]} no channel explains, {removed[2]} empty cells; {len(self.problems)} problems"
        ]
        lines += ["  " + s.line() for s in self.scans[:limit]]
        if len(self.scans) > limit:
            lines.append(f"  ... and {len(self.scans) - limit} more scans")
        lines += [f"  {p}: {m}" for p, m in self.problems[:limit]]
        return "\n".join(lines)


def scan_files(root: Path) -> list[Path]:
    """The scan files of a folder (sorted), or ``[root]`` for a file."""
    if root.is_file():
        return [root]
    return sorted(p for p in root.iterdir() if p.is_file() and scan_format(p) is not None)


def inspect_scans(
    root: str | Path, lidar: str | LidarSpec | None = None, min_range: float = DEFAULT_MIN_RANGE
) -> ScanReport:
    """Summarise every scan file under ``root`` (a folder or one file); see the module docstring.

    Raises:
        ValueError: An unknown ``lidar`` preset or a bad spec file (naming it).
    """
    root = Path(root)
    spec = None if lidar is None else load_lidar_spec(lidar)
    report = ScanReport(root, spec)
    files = scan_files(root)
    if not files:
        report.problems.append(
            (str(root), "no dataset.yaml and no LiDAR scan files (.bin, .pcd, .ply, .npy, ...)")
        )
    for path in files:
        try:
            scan = load_scan(path)
        except DatasetFormatError as err:
            report.problems.append((str(path), err.message))
            continue
        ring_source, per_ring = None, None
        rings = scan.rings
        if spec is not None:
            try:
                rings, ring_source = resolve_rings(scan.points, spec, scan.rings, scan.firing_order)
            except ValueError as err:
                report.problems.append((str(path), f"{err} ({spec.name or 'the LiDAR spec'})"))
                continue
        elif rings is not None:
            ring_source = "field"
        kept = filter_scan(scan.points, rings if rings is not None else np.zeros(len(scan.points)), min_range)
        if rings is not None:
            n_c = spec.channels if spec is not None else int(rings.max(initial=-1)) + 1
            per_ring = np.bincount(rings[kept.keep], minlength=n_c)
        report.scans.append(
            ScanSummary(
                path,
                scan.format,
                len(scan.points),
                ring_source,
                per_ring,
                kept.near_origin,
                kept.unexplained,
                scan.no_returns,
            )
        )
    return report


__all__ = ["ScanReport", "ScanSummary", "inspect_scans", "scan_files"]
