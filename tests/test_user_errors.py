"""Bad inputs to the real commands end in one line, ``error: <message naming the key or file>``, exit status 2.

Each row of the tables runs a console command the way a user meets it and checks the exit status, that the message
names the key or file, and that no traceback is printed. The rows run through the commands' own entry functions in
this process (``tests.helpers.commands.run_in_process``: ``argv``, stdout and stderr as a fresh process has them;
what a row changes in the process, ``ROW_PATCH``, is put back after it). Module fixtures run the rows once:
a representative set in the default suite, the other schema rows ``slow`` (every kind of schema key is also checked
by ``test_schema_table``). Rows on an empty dataset cache check that the command stopped before generating the
dataset. Every row checks that the refused command left no new file or folder, and removed none: in its temporary
folder (the run directories it names, the dataset cache), the dataset it read, the checkout's ``logs/`` and the
default data cache; one row leaves ``hydra.run.dir`` to its default, ``logs/<task>/runs/<name>`` under
``PROJECT_ROOT`` (set for every row to a folder of the temporary one that does not exist yet). The rows that need a
corrupted dataset load frames in a DataLoader worker and are ``slow``.
"""

from __future__ import annotations

import importlib.util
import os
import pickle
import shutil
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import torch
from hydra import compose, initialize_config_dir
from omegaconf import DictConfig
from torch.utils.data import DataLoader, Dataset

from airfisheye_bench.config_checks import RULES, check_common_values
from airfisheye_bench.errors import EXIT_USER_ERROR, ConfigError, UserError, report_user_errors, user_message
from airfisheye_bench.io.errors import DatasetFormatError
from tests.helpers.commands import (
    EVALUATE,
    EXPORT,
    INSPECT,
    INSPECT_ENTRY,
    TRAIN,
    Outcome,
    assert_one_line_error,
    run_command,
    run_in_process,
)
from tests.helpers.omni360_fixture import write_omni360_fixture
from tests.helpers.runs import tiny_run_overrides
from tests.helpers.woodscape_fixture import write_woodscape

ROOT = Path(__file__).resolve().parents[1]


# ------------------------------------------------------------------- rows run as commands (no corrupt dataset)
@pytest.mark.integration
def test_debug_switch_shows_the_traceback(tiny_dataset: Path, tmp_path: Path) -> None:
    args = [*tiny_run_overrides("seg", tiny_dataset), "trainer.max_epochs=abc", f"hydra.run.dir={tmp_path}"]
    outcome = run_command(TRAIN, args, debug=True)
    assert outcome.returncode != 0
    assert "Traceback" in outcome.stderr and "ConfigError: trainer.max_epochs='abc'" in outcome.stderr


#: What a row changes in the process before it runs: no download is tried in a test (huggingface_hub's
#: ``HF_HUB_OFFLINE``, read from the environment when it is imported, so set on its constants) and the cache is empty.
def _offline_hub(tmp: Path, patch: pytest.MonkeyPatch) -> None:
    from huggingface_hub import constants

    patch.setattr(constants, "HF_HUB_OFFLINE", True)
    patch.setattr(constants, "HF_HUB_CACHE", str(tmp / "hf" / "hub"))


ROW_PATCH: dict[str, Callable[[Path, pytest.MonkeyPatch], None]] = {"offline_weights": _offline_hub}


def _fast_rows(tmp: Path, dataset: Path) -> dict[str, tuple[str, list[str], tuple[str, ...]]]:
    """Row name -> (script, arguments, strings the message must contain); :data:`ROW_PATCH` prepares the process."""
    garbage = tmp / "garbage.bin"
    garbage.write_bytes(b"\x80\x04 this is not a checkpoint")
    onnx = tmp / "garbage.onnx"
    onnx.write_bytes(b"not a protobuf at all \xff\xff\xff")
    a_file = tmp / "a_file"
    a_file.write_text("x")
    ds_radtan = tmp / "camchain-ds-radtan.yaml"  # Kalibr's ds model takes no distortion; radtan is refused
    ds_radtan.write_text(
        "cam0:\n  camera_model: ds\n  distortion_model: radtan\n  distortion_coeffs: [0.01, 0.0, 0.0, 0.0]\n"
        "  intrinsics: [-0.17, 0.59, 158.3, 158.3, 254.9, 256.9]\n  resolution: [512, 512]\n"
    )
    bad_scan = tmp / "000000.bin"
    bad_scan.write_bytes(b"\0" * 20)  # not a whole number of float32 x 4 records
    bad_spec = tmp / "sensor.yaml"
    bad_spec.write_text("channels: 64\nelevations_deg: [2, 1]\n")
    woodscape = write_woodscape(tmp / "woodscape")
    omni360 = write_omni360_fixture(tmp / "omni360", height=8, frames=3)
    shutil.rmtree(omni360 / "NYC" / "nyc_Depth")  # a download without one scene's depth archive
    empty = tmp / "empty"  # a dataset folder with nothing in it
    empty.mkdir()
    existing = tmp / "existing_run"  # a run directory given by hydra.run.dir that exists: it stays
    existing.mkdir()
    train = [*tiny_run_overrides("seg", dataset)]
    # On the synthetic preset with an empty cache: a row refused before any work leaves the cache without a dataset.
    fresh = [*train, "data.root=null", "data.preset=tiny", f"paths.data_dir={tmp}/cache"]
    nan_predictions = tmp / "nan_predictions"
    for i, sample_id in enumerate((dataset / "splits" / "test.txt").read_text().split()):
        depth = np.full((64, 64), 10.0, np.float32)  # the served size of tiny_run_overrides
        depth[0, : i + 1] = np.nan
        (nan_predictions / sample_id).parent.mkdir(parents=True, exist_ok=True)
        np.save(nan_predictions / f"{sample_id}.npy", depth)
    return {
        "max_epochs": (
            TRAIN,
            [*train, "trainer.max_epochs=abc", f"hydra.run.dir={tmp}/r1"],
            ("trainer.max_epochs",),
        ),
        "camera_size": (
            TRAIN,
            [*train, "data.camera.size=abc", f"hydra.run.dir={tmp}/r2"],
            ("data.camera.size",),
        ),
        "lens_model": (
            TRAIN,
            [*fresh, "data.camera.model=fisheye9000", f"hydra.run.dir={tmp}/r3"],
            ("data.camera.model", "fisheye9000", "equidistant"),
        ),
        # The schema (airfisheye_bench.config_checks.RULES): types, ranges, choices, files.
        "max_epochs_negative": (
            TRAIN,
            [*fresh, "trainer.max_epochs=-3", f"hydra.run.dir={tmp}/r4"],
            ("trainer.max_epochs=-3", ">= -1"),
        ),
        "occlusion": (
            TRAIN,
            [*fresh, "data.occlusion=zbufer", f"hydra.run.dir={tmp}/r5"],
            ("data.occlusion='zbufer'", "zbuffer"),
        ),
        "source": (
            TRAIN,
            [*fresh, "data.source=pinhole", f"hydra.run.dir={tmp}/r6"],
            ("data.source='pinhole'", "cubemap, fisheye"),
        ),
        "hflip": (
            TRAIN,
            [*fresh, "data.augment.hflip=2", f"hydra.run.dir={tmp}/r7"],
            ("data.augment.hflip=2", "[0, 1]"),
        ),
        "bool": (TRAIN, [*fresh, "test=maybe", f"hydra.run.dir={tmp}/r8"], ("test='maybe'", "true or false")),
        "precision": (
            TRAIN,
            [*fresh, "trainer.precision=15-mixed", f"hydra.run.dir={tmp}/r9"],
            ("trainer.precision='15-mixed'", "16-mixed"),
        ),
        "accelerator": (
            TRAIN,
            [*fresh, "trainer.accelerator=gpx", f"hydra.run.dir={tmp}/r10"],
            ("trainer.accelerator='gpx'", "cuda"),
        ),
        "encoder_weights": (
            TRAIN,
            [*fresh, f"model.encoder_weights={tmp}/nope/resnet18.pth", f"hydra.run.dir={tmp}/r11"],
            ("model.encoder_weights", f"{tmp}/nope/resnet18.pth"),
        ),
        # A calibrated lens (data.camera.calibration): a missing file, and a model no reader supports.
        "calibration_missing": (
            TRAIN,
            [*fresh, f"data.camera.calibration={tmp}/nope/camchain.yaml", f"hydra.run.dir={tmp}/r16"],
            (f"data.camera.calibration='{tmp}/nope/camchain.yaml'", "no such file"),
        ),
        "calibration_model": (
            TRAIN,
            [*fresh, f"data.camera.calibration={ds_radtan}", f"hydra.run.dir={tmp}/r17"],
            (
                "data.camera.calibration",
                str(ds_radtan),
                "cam0.distortion_model",
                "ds-radtan is not supported",
                "ds-none",
            ),
        ),
        "root_missing": (
            TRAIN,
            [*train, f"data.root={tmp}/nowhere", f"hydra.run.dir={tmp}/r12"],
            (f"data.root='{tmp}/nowhere'", "no such folder"),
        ),
        "preset": (
            TRAIN,
            [*fresh, "data.preset=tiniest", f"hydra.run.dir={tmp}/r15"],
            ("data.preset='tiniest'", "tiny, quickstart"),
        ),
        "root_unset": (
            TRAIN,
            [*fresh, "data.preset=null", f"hydra.run.dir={tmp}/r13"],
            ("data.root", "data.preset"),
        ),
        "occlusion_options": (
            TRAIN,
            [*fresh, "data.occlusion=hpr", "data.occlusion_options={radius:0.5}", f"hydra.run.dir={tmp}/r20"],
            ("data.occlusion_options", "radius must be a number > 1"),
        ),
        "lidar_min_range": (
            TRAIN,
            [*fresh, "data.lidar.min_range=-1", f"hydra.run.dir={tmp}/r21"],
            ("data.lidar.min_range=-1", ">= 0"),
        ),
        "lidar_density": (
            TRAIN,
            [*fresh, "data.lidar.density=sparse", f"hydra.run.dir={tmp}/r22"],
            ("data.lidar.density='sparse'", "native, paper"),
        ),
        "lidar_preset": (
            TRAIN,
            [*fresh, "data.lidar.preset=hdl65e", f"hydra.run.dir={tmp}/r16"],
            ("data.lidar.preset='hdl65e'", "hdl64e"),
        ),
        "lidar_spec_file": (
            TRAIN,
            [*train, f"data.lidar.preset={bad_spec}", f"hydra.run.dir={tmp}/r17"],
            (str(bad_spec), "strictly ascending"),
        ),
        "scan_file": (
            INSPECT,
            [INSPECT_ENTRY, f"root={bad_scan}", "lidar=hdl64e"],
            (str(bad_scan), "float32 x 4"),
        ),
        "inspect_lidar": (
            INSPECT,
            [INSPECT_ENTRY, f"root={tmp}", "lidar=hdl65e"],
            ("lidar='hdl65e'", "vlp16"),
        ),
        "ckpt_missing": (
            TRAIN,
            [*train, f"ckpt_path={tmp}/nope.ckpt", f"hydra.run.dir={tmp}/r14"],
            (f"ckpt_path='{tmp}/nope.ckpt'", "no such file"),
        ),
        "encoding": (
            EVALUATE,
            [f"ckpt_path={garbage}", "prediction_format=tiff", f"hydra.run.dir={tmp}/e3"],
            ("prediction_format='tiff'", "png, npy"),
        ),
        "tta": (
            EVALUATE,
            [f"ckpt_path={garbage}", "tta=flop", f"hydra.run.dir={tmp}/e4"],
            ("tta='flop'", "flip"),
        ),
        "split": (
            EVALUATE,
            [f"ckpt_path={garbage}", "split=train", f"hydra.run.dir={tmp}/e5"],
            ("split='train'", "val, test"),
        ),
        "onnx_missing": (
            EVALUATE,
            [f"onnx_path={tmp}/nope.onnx", f"hydra.run.dir={tmp}/e6"],
            (f"onnx_path='{tmp}/nope.onnx'", "no such file"),
        ),
        "predictions_nan": (
            EVALUATE,
            [
                "task=depth",
                f"predictions={nan_predictions}",
                f"data.root={dataset}",
                "data.camera.size=64",
                f"hydra.run.dir={tmp}/e0",
            ],
            (str(nan_predictions),),
        ),
        "onnx_garbage": (EVALUATE, [f"onnx_path={onnx}", f"hydra.run.dir={tmp}/e1"], (str(onnx), "ONNX")),
        "ckpt_garbage": (EVALUATE, [f"ckpt_path={garbage}", f"hydra.run.dir={tmp}/e2"], (str(garbage),)),
        "export_proc": (EXPORT, [f"ckpt_path={garbage}", "out=/proc/x.onnx"], ("out=/proc/x.onnx",)),
        "export_sys": (EXPORT, [f"ckpt_path={garbage}", "out=/sys/x.onnx"], ("out=/sys/x.onnx",)),
        "export_parent_file": (
            EXPORT,
            [f"ckpt_path={garbage}", f"out={a_file}/x.onnx"],
            (f"{a_file}/x.onnx", f"{a_file} is a file"),
        ),
        "export_ckpt_garbage": (EXPORT, [f"ckpt_path={garbage}", f"out={tmp}/x.onnx"], (str(garbage),)),
        # Hydra's own answer was a "+trainer.max_epoch=1" hint; the nearest key instead.
        "unknown_key": (
            TRAIN,
            [*fresh, "trainer.max_epoch=1", f"hydra.run.dir={tmp}/r16"],
            ("trainer.max_epoch=1", "did you mean trainer.max_epochs=1"),
        ),
        "unknown_option": (
            TRAIN,
            [*fresh, "logger=tensorbord", f"hydra.run.dir={tmp}/r17"],
            ("logger=tensorbord", "logger=tensorboard"),
        ),
        "logger_missing": (  # where tensorboard is not installed (test_logger_missing_row_applies says)
            TRAIN,
            [*fresh, "logger=tensorboard", f"hydra.run.dir={tmp}/r18"],
            ("logger.tensorboard", "airfisheye-bench[tensorboard]"),
        ),
        "woodscape_depth": (  # a dataset without the content a task needs
            TRAIN,
            [
                "task=depth",
                "data=woodscape",
                f"data.root={woodscape}",
                "trainer=debug",
                f"hydra.run.dir={tmp}/r20",
            ],
            ("WoodScape released no LiDAR and no depth", "#82", "task=depth needs it"),
        ),
        "omni360_depth": (  # a scene without its depth folder
            TRAIN,
            [
                "task=depth",
                "data=omni360",
                f"data.root={omni360}",
                "trainer=debug",
                f"hydra.run.dir={tmp}/r26",
            ],
            (str(omni360 / "NYC"), "no depth folder", "task=depth needs it"),
        ),
        # Refused on the dataset itself, before the run directory is written: nothing of the run is left.
        "root_empty": (
            TRAIN,
            [*train, f"data.root={empty}", f"hydra.run.dir={tmp}/r23"],
            (f"{empty}/dataset.yaml", "does not exist"),
        ),
        "run_dir_exists": (
            TRAIN,
            [*train, f"data.root={empty}", f"hydra.run.dir={existing}"],
            (f"{empty}/dataset.yaml",),
        ),
        "run_dir_default": (  # logs/seg/runs/<name> under PROJECT_ROOT: made by Hydra, taken back
            TRAIN,
            [*train, f"data.root={empty}"],
            (f"{empty}/dataset.yaml",),
        ),
        "woodscape_views": (
            TRAIN,
            [
                *tiny_run_overrides("seg", woodscape),
                "data=woodscape",
                "data.format_options.views=[FV,XX]",
                f"hydra.run.dir={tmp}/r24",
            ],
            ("data.format_options.views", "XX"),
        ),
        "woodscape_depth_root_empty": (  # what the format never has is said before its folder is read
            TRAIN,
            [
                "task=depth",
                "data=woodscape",
                f"data.root={empty}",
                "trainer=debug",
                f"hydra.run.dir={tmp}/r25",
            ],
            ("WoodScape released no LiDAR and no depth", "task=depth needs it"),
        ),
        "offline_weights": (
            TRAIN,
            [*train, "experiment=paper/seg", "data.camera.size=64", f"hydra.run.dir={tmp}/r19"],
            ("encoder_weights='imagenet'", "HF_HUB_OFFLINE is set", str(tmp / "hf")),
        ),
    }


@dataclass(frozen=True)
class RowOutcomes:
    tmp: Path
    outcomes: dict[str, Outcome]
    names: dict[str, tuple[str, ...]]
    #: The files and folders each row added or removed (none, for a refused command).
    changes: dict[str, list[str]]


def _tree(*roots: Path) -> set[str]:
    """Every file and folder under ``roots`` (the roots too, where they exist)."""
    found = set()
    for root in roots:
        if root.exists():
            found |= {str(root), *(str(p) for p in root.rglob("*"))}
    return found


def _watched(tmp: Path, dataset: Path) -> set[str]:
    """What a row might write to: its temporary folder, the dataset, the checkout's ``logs/`` and top level (where
    ``paths.root_dir`` points by default), the top level of the default data cache."""
    cache = Path(os.environ.get("AIRFISHEYE_DATA", Path.home() / ".cache" / "airfisheye-bench"))
    tops = {str(p) for folder in (ROOT, cache) if folder.is_dir() for p in folder.iterdir()}
    tops = {p for p in tops if not Path(p).name.startswith(".") and Path(p).name != "__pycache__"}
    return _tree(tmp, dataset, ROOT / "logs") | tops


def _run_rows(tmp: Path, dataset: Path, selected: tuple[str, ...]) -> RowOutcomes:
    """The selected rows, each run once in this process through the command's entry function."""
    rows = {name: row for name, row in _fast_rows(tmp, dataset).items() if name in selected}
    if _has_tensorboard():
        rows.pop("logger_missing", None)
    outcomes, changes = {}, {}
    # paths.root_dir (logs/ of a run directory left to its default): a folder that does not exist yet.
    env = {"PROJECT_ROOT": str(tmp / "project")}
    for name, (script, args, _) in rows.items():
        before = _watched(tmp, dataset)
        with pytest.MonkeyPatch.context() as patch:
            if name in ROW_PATCH:
                ROW_PATCH[name](tmp, patch)
            outcomes[name] = run_in_process(script, args, extra_env=env)
        after = _watched(tmp, dataset)
        changes[name] = sorted(f"+{p}" for p in after - before) + sorted(f"-{p}" for p in before - after)
    return RowOutcomes(tmp, outcomes, {name: names for name, (_, _, names) in rows.items()}, changes)


def _has_tensorboard() -> bool:
    return any(importlib.util.find_spec(m) is not None for m in ("tensorboard", "tensorboardX"))


FAIL_FAST = (
    "unknown_key",
    "unknown_option",
    "logger_missing",
    "lens_model",
    "max_epochs_negative",
    "occlusion",
    "source",
    "hflip",
    "bool",
    "precision",
    "accelerator",
    "encoder_weights",
    "preset",
    "root_unset",
    "calibration_missing",
    "calibration_model",
    "lidar_preset",
    "occlusion_options",
    "lidar_min_range",
    "lidar_density",
)
"""Rows on the synthetic preset with an empty cache, refused before the dataset is generated."""

DEFAULT_ROWS = (
    "max_epochs",
    "camera_size",
    "lens_model",
    "occlusion",
    "calibration_missing",
    "calibration_model",
    "root_missing",
    "encoding",
    "predictions_nan",
    "onnx_garbage",
    "ckpt_garbage",
    "export_proc",
    "export_sys",
    "export_parent_file",
    "export_ckpt_garbage",
    "unknown_key",
    "unknown_option",
    "logger_missing",
    "offline_weights",
    "lidar_preset",
    "scan_file",
    "occlusion_options",
    "woodscape_depth",
    "omni360_depth",
    "root_empty",
    "run_dir_exists",
    "run_dir_default",
    "woodscape_views",
    "woodscape_depth_root_empty",
)
"""Rows of the default suite; the other schema rows are ``slow`` (test_schema_table covers them in-process)."""
SLOW_ROWS = (
    "max_epochs_negative",
    "source",
    "hflip",
    "bool",
    "precision",
    "accelerator",
    "encoder_weights",
    "preset",
    "root_unset",
    "ckpt_missing",
    "tta",
    "split",
    "onnx_missing",
    "lidar_spec_file",
    "inspect_lidar",
    "lidar_min_range",
    "lidar_density",
)


@pytest.fixture(scope="module")
def fast_rows(tiny_dataset: Path, tmp_path_factory: pytest.TempPathFactory) -> RowOutcomes:
    return _run_rows(tmp_path_factory.mktemp("user_errors"), tiny_dataset, DEFAULT_ROWS)


@pytest.fixture(scope="module")
def slow_rows(tiny_dataset: Path, tmp_path_factory: pytest.TempPathFactory) -> RowOutcomes:
    return _run_rows(tmp_path_factory.mktemp("user_errors_slow"), tiny_dataset, SLOW_ROWS)


def _check_row(row: str, rows: RowOutcomes) -> None:
    if row == "logger_missing" and _has_tensorboard():
        pytest.skip("tensorboard is installed here: the row needs it missing")
    message = assert_one_line_error(rows.outcomes[row], *rows.names[row])
    assert not rows.changes[row], rows.changes[row]  # a refused command writes nothing, removes nothing
    if row in ("ckpt_garbage", "export_ckpt_garbage"):
        assert "weights_only" not in message  # PyTorch's advice to unpickle anything is not repeated
    if row in FAIL_FAST:  # refused before the dataset was generated (none of them gets that far)
        assert not any((rows.tmp / "cache").rglob("dataset.yaml"))
    if row == "predictions_nan":  # every file is listed under the error line, with its count of NaN
        folder = rows.tmp / "nan_predictions"
        for path in folder.rglob("*.npy"):
            nan = int(np.isnan(np.load(path)).sum())
            assert f"{path.relative_to(folder)}: {nan} of " in rows.outcomes[row].stderr
    if row.startswith("export_"):
        assert not list(rows.tmp.glob("*x.onnx*"))
    if row == "offline_weights":  # no download tried, so none retried
        assert "Retry" not in rows.outcomes[row].stdout + rows.outcomes[row].stderr
    if row in ("unknown_key", "unknown_option"):
        assert "+trainer" not in message and "Could not" not in rows.outcomes[row].stderr


@pytest.mark.integration
@pytest.mark.parametrize("row", DEFAULT_ROWS)
def test_fast_rows(row: str, fast_rows: RowOutcomes) -> None:
    _check_row(row, fast_rows)


@pytest.mark.slow
@pytest.mark.parametrize("row", SLOW_ROWS)
def test_slow_rows(row: str, slow_rows: RowOutcomes) -> None:
    _check_row(row, slow_rows)


SCHEMA_TABLE = [
    # (config, overrides, what the message must contain)
    ("train", ["trainer.max_epochs=abc"], "trainer.max_epochs='abc': expected an integer >= -1"),
    ("train", ["trainer.max_epochs=-3"], "trainer.max_epochs=-3: expected an integer >= -1"),
    ("train", ["trainer.devices=0"], "trainer.devices=0: expected a device count"),
    (
        "train",
        ["trainer=debug", "trainer.limit_train_batches=-1"],
        "trainer.limit_train_batches=-1: expected a number",
    ),
    ("train", ["trainer.accelerator=gpx"], "trainer.accelerator='gpx': expected one of auto, gpu"),
    ("train", ["trainer.precision=15-mixed"], "trainer.precision='15-mixed': expected one of"),
    ("train", ["data.camera.size=abc"], "data.camera.size='abc': expected an integer >= 8"),
    ("train", ["data.camera.fov_deg=wide"], "data.camera.fov_deg='wide': expected a number"),
    (
        "train",
        ["data.camera.model=pinhole", "data.camera.fov_deg=180"],
        "data.camera.fov_deg=180: fov_deg must be in (0, 180), got 180.0 (data.camera.model=pinhole)",
    ),
    (
        "train",
        ["data.camera.model=orthographic", "data.camera.fov_deg=200"],
        "data.camera.fov_deg=200: fov_deg=200.0 cannot be represented by the orthographic model",
    ),
    (
        "train",
        ["data.camera.model=fisheye9000"],
        "data.camera.model='fisheye9000': expected one of equidistant",
    ),
    (
        "train",
        ["data.camera.calibration=/nonexistent/camchain.yaml"],
        "data.camera.calibration='/nonexistent/camchain.yaml': no such file",
    ),
    (
        "train",
        ["data.camera.calibration=/"],
        "data.camera.calibration='/': is a folder, expected a calibration file",
    ),
    ("train", ["data.camera.fit=stretch"], "data.camera.fit='stretch': expected one of pad, crop"),
    ("evaluate", ["allow_camera_mismatch=sure"], "allow_camera_mismatch='sure': expected true or false"),
    ("train", ["data.occlusion=zbufer"], "data.occlusion='zbufer': expected one of ordering"),
    (
        "train",
        ["data.occlusion=zbuffer", "data.occlusion_options={size:3}"],
        "data.occlusion_options={'size': 3}: unknown option(s) ['size'] for method 'zbuffer'",
    ),
    (
        "train",
        ["data.occlusion=hpr", "data.occlusion_options={radius:0.5}"],
        "data.occlusion_options={'radius': 0.5}: radius must be a number > 1",
    ),
    (
        "train",
        ["data.gimbal={pitch_deg:[45,0]}"],
        "data.gimbal={'pitch_deg': [45, 0]}: pitch_deg=[45, 0]: expected a number of degrees or [low, high]",
    ),
    (
        "train",
        ["data.gimbal=[0,30,0,1]"],
        "data.gimbal=[0, 30, 0, 1]: view [0, 30, 0, 1]: expected [yaw, pitch] or",
    ),
    (
        "train",
        ["data.gimbal=[0,30]", "data.source=fisheye"],
        "data.gimbal=[0, 30]: needs data.source=cubemap",
    ),
    ("train", ["data.format=kitti"], "data.format='kitti': expected one of airfisheye"),
    (
        "train",
        ["data.format_options={camera:image_03}"],
        "data.format_options={'camera': 'image_03'}: unknown keys ['camera'] for data.format=airfisheye",
    ),
    ("train", ["data.lidar.min_range=-1"], "data.lidar.min_range=-1: expected a number >= 0"),
    ("train", ["data.lidar.density=sparse"], "data.lidar.density='sparse': expected one of native, paper"),
    ("train", ["data.lidar.preset=hdl65e"], "data.lidar.preset='hdl65e': expected one of hdl32e, hdl64e"),
    ("train", ["data.lidar.preset=/"], "data.lidar.preset='/': expected one of"),
    ("train", ["+data.camera.k=[0.1,0.2]"], "data.camera.k=[0.1, 0.2]: expected four numbers"),
    ("train", ["data.camera.camera=-1"], "data.camera.camera=-1: expected a camera name or a 0-based index"),
    ("train", ["data.source=pinhole"], "data.source='pinhole': expected one of cubemap, fisheye"),
    ("train", ["data.remap_on=gpu"], "data.remap_on='gpu': expected one of worker, device"),
    (
        "train",
        ["data.remap_on=device", "data.source=fisheye"],
        "data.remap_on='device': data.source=fisheye has no cube faces to remap",
    ),
    (
        "train",
        ["data.remap_on=device", "data.gimbal={pitch_deg:[0,45]}"],
        "data.remap_on='device': data.gimbal turns the samples of a split to views of their own",
    ),
    ("train", ["data.augment.hflip=2"], "data.augment.hflip=2: expected a number in [0, 1]"),
    ("train", ["data.batch_size=0"], "data.batch_size=0: expected an integer >= 1"),
    ("train", ["data.motion_compensation=maybe"], "data.motion_compensation='maybe': expected true or false"),
    ("train", ["data.root=/nonexistent/airfisheye"], "data.root='/nonexistent/airfisheye': no such folder"),
    (  # the folder a format reads is described as that format lays it out
        "train",
        ["data=kitti360", "task=completion", "data.root=/nonexistent/kitti360"],
        "data.root='/nonexistent/kitti360': no such folder (the root of the kitti360 dataset",
    ),
    ("train", ["ckpt_path=/nonexistent.ckpt"], "ckpt_path='/nonexistent.ckpt': no such file or folder"),
    ("train", ["model.encoder_weights=/nonexistent/r18.pth"], "model.encoder_weights='/nonexistent/r18.pth'"),
    (
        "train",
        ["+model.weights_path=/nonexistent/m.pt"],
        "model.weights_path='/nonexistent/m.pt': no such file",
    ),
    ("train", ["compile=1"], "compile=1: expected true or false"),
    ("evaluate", ["prediction_format=tiff"], "prediction_format='tiff': expected one of png, npy"),
    ("evaluate", ["tta=flop"], "tta='flop': expected one of flip"),
    ("evaluate", ["split=train"], "split='train': expected one of val, test"),
    ("evaluate", ["device=tpu"], "device='tpu': expected one of auto, cpu, cuda"),
    ("evaluate", ["num_panels=-1"], "num_panels=-1: expected an integer >= 0"),
    ("evaluate", ["onnx_path=/nonexistent.onnx"], "onnx_path='/nonexistent.onnx': no such file"),
    ("evaluate", ["predictions=/nonexistent/preds"], "predictions='/nonexistent/preds': no such folder"),
]


# ---------------------------------------------------------------------------------- the schema and the wrapper
def test_unknown_preset_is_refused_before_generation(tmp_path: Path) -> None:
    """The preset names live in the generator (above the schema): the datamodule checks them when built."""
    from airfisheye_bench.synth.presets import PRESETS
    from datamodules import AirFisheyeDataModule

    with pytest.raises(ConfigError, match=r"data\.preset='tiniest': expected one of") as caught:
        AirFisheyeDataModule("seg", preset="tiniest", cache_dir=tmp_path)
    assert all(name in str(caught.value) for name in PRESETS)
    assert not any(tmp_path.iterdir())


@pytest.mark.integration
def test_a_missing_optional_package_names_its_extra(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``logger=mlflow`` / ``mlflow_run=`` without mlflow installed (``EXTRAS``): one line naming the key and the
    extra to install, before any work (the dataset cache stays empty). The package is hidden from the commands as
    if it were not installed (``sys.modules['mlflow'] = None``: importing it fails, ``find_spec`` finds nothing)."""
    monkeypatch.setitem(sys.modules, "mlflow", None)
    cache = [f"paths.data_dir={tmp_path}/cache"]
    rows = {
        TRAIN: ["task=seg", "data.preset=tiny", *cache, "logger=mlflow", f"hydra.run.dir={tmp_path}/r"],
        EVALUATE: [f"ckpt_path={tmp_path}", "mlflow_run=auto", *cache, f"hydra.run.dir={tmp_path}/e"],
        EXPORT: [f"ckpt_path={tmp_path}", f"out={tmp_path}/x.onnx", "mlflow_run=auto"],
    }
    for script, args in rows.items():
        key = "logger.mlflow" if script == TRAIN else "mlflow_run"
        assert_one_line_error(
            run_in_process(script, args),
            f"{key} needs the Python package mlflow",
            'pip install -e ".[mlflow]"',
        )
    assert not (tmp_path / "cache").exists() and not (tmp_path / "x.onnx").exists()


def _compose(config: str, overrides: list[str]) -> DictConfig:
    with initialize_config_dir(config_dir=str(ROOT / "configs"), version_base="1.3"):
        return compose(config_name=config, overrides=overrides)


def _rules(config: str) -> list:
    from airfisheye_bench.evaluation.command import EVALUATE_RULES

    return [RULES, EVALUATE_RULES] if config == "evaluate" else [RULES]


@pytest.mark.parametrize("config", sorted({config for config, _, _ in SCHEMA_TABLE}))
def test_the_schema_passes_the_defaults(config: str) -> None:
    """What the table's rows are refused against: the defaults of each command pass every rule."""
    for table in _rules(config):
        check_common_values(_compose(config, []), table)


@pytest.mark.parametrize(("config", "overrides", "expected"), SCHEMA_TABLE)
def test_schema_table(config: str, overrides: list[str], expected: str) -> None:
    """Every kind of checked key: the message names the key, the value and what is expected (in-process)."""
    rules = _rules(config)
    cfg = _compose(config, overrides)
    with pytest.raises(UserError) as caught:
        for table in rules:
            check_common_values(cfg, table)
    assert expected in str(caught.value)


# ------------------------------------------------------------------------------------- the wrapper in-process
def test_wrapper_exits_2_on_user_errors_and_reraises_bugs(capsys: pytest.CaptureFixture[str]) -> None:
    @report_user_errors
    def fails(error: Exception) -> None:
        raise error

    with pytest.raises(SystemExit) as stop:
        fails(ConfigError("data.batch_size=0: expected an integer >= 1"))
    assert stop.value.code == EXIT_USER_ERROR
    assert capsys.readouterr().err == "error: data.batch_size=0: expected an integer >= 1\n"
    with pytest.raises(ZeroDivisionError):  # a bug keeps its traceback
        fails(ZeroDivisionError("division by zero"))
    with pytest.raises(ValueError, match="not a user error"):  # a plain ValueError is not assumed to be one
        fails(ValueError("not a user error"))


class _BrokenFrames(Dataset):
    """Frame 1 is a corrupt file (a user error), frame 2 a bug."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def __len__(self) -> int:
        return 3

    def __getitem__(self, index: int) -> torch.Tensor:
        if index == 1:
            raise DatasetFormatError(self.path, "cannot decode image (image file is truncated)")
        if index == 2:
            raise KeyError("a bug")
        return torch.zeros(1)


@pytest.mark.parametrize(
    ("index", "expected"),
    [(1, lambda path: f"{path}: cannot decode image (image file is truncated)"), (2, lambda path: None)],
)
def test_loader_worker_errors_keep_their_message(
    index: int, expected: Callable[[Path], str | None], tmp_path: Path
) -> None:
    path = tmp_path / "rgb" / "000001.png"
    batches = iter(DataLoader(torch.utils.data.Subset(_BrokenFrames(path), [index]), num_workers=1))
    try:
        with pytest.raises(Exception) as caught:
            next(batches)
    finally:  # the worker stops now: left to the collector, its join cost a later test 5 s
        batches._shutdown_workers()
    assert user_message(caught.value) == expected(path)


# ------------------------------------------------------------------------------ slow rows (corrupt datasets)
def _truncate(path: Path) -> None:
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 3])


def _pickled_npy(path: Path) -> None:
    np.save(path, np.array([{"points": "object"}], dtype=object), allow_pickle=True)


def _garbage_yaml(path: Path) -> None:
    path.write_text("fx: [1, 2\n  :: not yaml ::\n")


CORRUPTIONS: dict[str, tuple[str, str, Callable[[Path], None]]] = {
    # name: (task, the files to corrupt (a glob in the training trajectory of the tiny preset), corruption)
    "truncated_png": ("seg", "cubemap/front/rgb/*.png", _truncate),
    "truncated_npy": ("completion", "lidar/*.npy", _truncate),
    "pickled_npy": ("completion", "lidar/*.npy", _pickled_npy),
    "garbage_calib": ("seg", "calib.yaml", _garbage_yaml),
}


@pytest.mark.slow
@pytest.mark.parametrize("row", [*sorted(CORRUPTIONS), "missing_split"])
def test_corrupt_dataset_rows(row: str, tiny_dataset: Path, tmp_path: Path) -> None:
    root = tmp_path / "dataset"
    shutil.copytree(tiny_dataset, root)
    if row == "missing_split":
        task, targets = "seg", [root / "splits" / "val.txt"]
        targets[0].unlink()
    else:
        task, pattern, corrupt = CORRUPTIONS[row]
        trajectory = (root / "splits" / "train.txt").read_text().split()[0].rpartition("/")[0]
        targets = sorted((root / trajectory).glob(pattern))
        assert targets, f"the tiny preset has no {trajectory}/{pattern}"
        for target in targets:  # every frame: which ones a short run reads first depends on the shuffle
            corrupt(target)
    args = [
        *tiny_run_overrides(task, root),
        "data.num_workers=1",  # read frames in a loader worker, as a real run does
        "test=false",
        f"hydra.run.dir={tmp_path / 'run'}",
    ]
    message = assert_one_line_error(run_command(TRAIN, args))
    assert any(str(target) in message for target in targets), message


def test_pickle_free_checkpoint_message_is_ours(tmp_path: Path) -> None:
    """The in-process reader gives the same message the commands print (no advice to unpickle anything)."""
    from airfisheye_bench.errors import InputFileError
    from airfisheye_bench.runs import read_checkpoint

    path = tmp_path / "evil.ckpt"
    path.write_bytes(pickle.dumps(ConfigError("an arbitrary object"), protocol=2))
    with pytest.raises(InputFileError, match=r"evil\.ckpt: not a readable checkpoint") as caught:
        read_checkpoint(path)
    assert "weights_only" not in str(caught.value)


def test_a_logger_without_its_package_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    """In-process, with tensorboard hidden: the row above runs only where it is not installed."""
    from airfisheye_bench import config_checks

    real = importlib.util.find_spec
    hidden = {"tensorboard", "tensorboardX"}
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name in hidden else real(name, *a)
    )
    cfg = _compose("train", ["logger=tensorboard"])
    with pytest.raises(
        ConfigError, match=r"logger.tensorboard needs the Python package tensorboard.*\[tensorboard\]"
    ):
        config_checks.check_extras(cfg)
    config_checks.check_extras(_compose("train", ["logger=csv"]))
    extras = (ROOT / "pyproject.toml").read_text()
    assert 'tensorboard = ["tensorboard' in extras  # the extra the message names exists
