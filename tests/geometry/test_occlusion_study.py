"""``scripts/occlusion_study.py`` runs end to end on the ``tiny`` dataset (only what holds by construction)."""

from __future__ import annotations

import json
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
from PIL import Image

from tests.scripts import load_script


@pytest.fixture(scope="module")
def study() -> ModuleType:
    return load_script("occlusion_study")


def test_main_tiny(
    study: ModuleType, tiny_dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    figure, out = tmp_path / "overlay.png", tmp_path / "study.json"
    argv = ["--root", str(tiny_dataset), "--frames", "2", "--size", "32", "--figure-scale", "1"]
    payload = study.main([*argv, "--figure", str(figure), "--json", str(out)])

    assert json.loads(out.read_text())["results"].keys() == {"32"}
    assert 1 <= payload["frames"] <= 2
    rows = {name: row["pooled"] for name, row in payload["results"]["32"]["rows"].items()}
    assert set(rows) == {name for name, _, _ in study.VARIANTS} | {study.ORACLE}
    none = rows["none"]
    assert none["kept"] > 0
    for name, row in rows.items():
        assert row["truth"] == none["truth"], name  # one ground truth for every row
        for key in ("precision", "recall", "f1"):
            assert 0.0 <= row[key] <= 1.0, (name, key)
        assert row["sparse_wrong"] <= row["sparse_gt"] <= row["sparse_px"]
        assert row["sparse_gt"] + row["sparse_no_gt"] == row["sparse_px"]
    # `none` keeps every projected point: all the visible ones, and the hidden ones too.
    assert none["recall"] == 1.0
    assert none["tp"] == none["truth"] and none["hidden_kept"] == none["kept"] - none["truth"]
    for name in ("ordering", "zbuffer"):  # occlusion tests only remove projected points
        assert rows[name]["kept"] <= none["kept"] and rows[name]["hidden_kept"] <= none["hidden_kept"]
    assert rows[study.ORACLE]["precision"] == rows[study.ORACLE]["recall"] == 1.0

    assert "| 32² | ordering |" in capsys.readouterr().out
    size = payload["figure"]["size"]
    width, height = Image.open(figure).size
    assert width == 3 * size + 2 * 4 and height > size  # three panels, gap 4, label strips on top


def test_sparse_map_is_the_served_input(study: ModuleType, tiny_dataset: Path) -> None:
    from datamodules.dataset import AirFisheyeDataset, CameraConfig

    served = AirFisheyeDataset(tiny_dataset, "test", "completion", camera=CameraConfig(size=32))
    frame = study.load_frame(study.make_datasets(tiny_dataset, "test", "cubemap", 32, 120.0), 0)
    ours = study.sparse_map(
        frame.points, frame.T[True], served.camera, frame.spec, "ordering", 120.0, served.valid_mask.numpy()
    )
    np.testing.assert_array_equal(ours, served[0]["sparse_depth"][0].numpy())
