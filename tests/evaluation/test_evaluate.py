"""``scripts/evaluate.py``: a checkpoint and its prediction files give the training run's test metrics."""

from __future__ import annotations

import json
from pathlib import Path

import lightning as L
import pytest

from airfisheye_bench.errors import ConfigError
from airfisheye_bench.evaluation import SubmissionError, load_entry
from airfisheye_bench.evaluation.command import evaluate
from tests.helpers.commands import EVALUATE, run_in_process
from tests.helpers.configs import compose_eval

pytestmark = pytest.mark.integration  # trains, evaluates or exports: seconds per test


@pytest.fixture(scope="module")
def depth_run(tiny_runs) -> Path:
    """The session's one-epoch AdaBins run on tiny data, tested on its test split (``results.json``)."""
    return tiny_runs("depth")


def _assert_same_metrics(a: dict, b: dict, abs_tol: float = 1e-6) -> None:
    assert a.keys() == b.keys()
    for key, value in a.items():
        if value is None:
            assert b[key] is None, key
        else:
            assert b[key] == pytest.approx(value, abs=abs_tol), key


def test_checkpoint_then_prediction_files(depth_run: Path, tmp_path: Path) -> None:
    trained = json.loads((depth_run / "results.json").read_text())
    preds = tmp_path / "preds"
    record = evaluate(
        compose_eval(
            [f"ckpt_path={depth_run}", "num_workers=0", f"save_predictions={preds}", "prediction_format=npy"],
            tmp_path / "ckpt",
        ),
    )
    # The same checkpoint, data and metric code as the training run's test stage.
    _assert_same_metrics(trained["metrics"], record["metrics"])
    assert record["model"]["source"] == "checkpoint" and record["model"]["sha256"]
    assert record["config"]["data"]["camera"]["size"] == 64  # the run's data configuration was used
    assert any(k.startswith("range_0-10/") for k in record["breakdown"])
    assert any(k.startswith("ring_80-95/") for k in record["breakdown"])
    assert len(list((tmp_path / "ckpt" / "panels").glob("*.png"))) == record["config"]["num_frames"] == 2
    assert json.loads((tmp_path / "ckpt" / "results.json").read_text())["metrics"] == record["metrics"]

    # The saved predictions, scored as a submission against the same data, give identical numbers.
    data = [f"data.root={record['config']['data']['root']}", "data.camera.size=64"]
    files = evaluate(
        compose_eval(["task=depth", f"predictions={preds}", "num_workers=1", *data], tmp_path / "files")
    )
    _assert_same_metrics(record["metrics"], files["metrics"])
    _assert_same_metrics(record["breakdown"], files["breakdown"])
    assert files["model"]["source"] == "predictions" and files["model"]["name"] == "preds"


def test_png_predictions_within_quantisation(depth_run: Path, tmp_path: Path) -> None:
    preds = tmp_path / "preds"
    record = evaluate(
        compose_eval([f"ckpt_path={depth_run}", "num_workers=0", f"save_predictions={preds}"], tmp_path / "a")
    )
    data = [f"data.root={record['config']['data']['root']}", "data.camera.size=64"]
    files = evaluate(
        compose_eval(["task=depth", f"predictions={preds}", "num_workers=0", *data], tmp_path / "b")
    )
    assert files["metrics"]["rmse"] == pytest.approx(record["metrics"]["rmse"], abs=2e-3)
    assert files["metrics"]["abs_rel"] == pytest.approx(record["metrics"]["abs_rel"], abs=1e-3)


def test_checkpoint_without_run_directory(tiny_dataset: Path, tmp_path: Path) -> None:
    """A bare checkpoint (no config.yaml next to it) is evaluated on the configured data."""
    from airfisheye_bench.tasks import SegmentationTask
    from datamodules import AirFisheyeDataModule

    dm = AirFisheyeDataModule("seg", root=tiny_dataset, camera={"size": 64})
    module = SegmentationTask(
        {"name": "deeplabv3plus", "encoder_name": "resnet18"},
        class_names=dm.class_names,
        palette=dm.palette[:13].tolist(),
    )
    trainer = L.Trainer(logger=False, enable_progress_bar=False, enable_model_summary=False)
    trainer.strategy.connect(module)
    ckpt = tmp_path / "bare.ckpt"
    trainer.save_checkpoint(ckpt)
    record = evaluate(
        compose_eval(
            [
                f"ckpt_path={ckpt}",
                f"data.root={tiny_dataset}",
                "data.camera.size=64",
                "num_workers=0",
                "num_panels=1",
                "name=untrained",
            ],
            tmp_path / "out",
        )
    )
    assert record["task"] == "seg" and record["model"]["run_name"] == "untrained"
    assert record["model"]["name"] == "deeplabv3plus"
    assert 0.0 <= record["metrics"]["mIoU"] <= 1.0
    assert any(k.startswith("IoU/") for k in record["metrics"])
    assert not any(k.startswith("range_") for k in record["breakdown"])  # seg: rings only
    assert len(list((tmp_path / "out" / "panels").glob("*.png"))) == 1


def test_source_and_task_errors(depth_run: Path, tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="exactly one of"):
        evaluate(compose_eval([], tmp_path))
    with pytest.raises(ValueError, match="exactly one of"):
        evaluate(compose_eval([f"ckpt_path={depth_run}", f"predictions={tmp_path}"], tmp_path))
    with pytest.raises(ValueError, match="needs task="):
        evaluate(compose_eval([f"predictions={tmp_path}"], tmp_path))
    with pytest.raises(ValueError, match=r"task=seg was requested but checkpoint .* is a depth model"):
        evaluate(compose_eval(["task=seg", f"ckpt_path={depth_run}"], tmp_path))
    with pytest.raises(FileNotFoundError, match="does not exist"):
        evaluate(compose_eval([f"ckpt_path={tmp_path / 'nope.ckpt'}"], tmp_path))
    bad = tmp_path / "bad.ckpt"
    bad.write_bytes(b"not a checkpoint")
    with pytest.raises(ValueError, match=r"bad\.ckpt: not a readable checkpoint"):
        evaluate(compose_eval([f"ckpt_path={bad}"], tmp_path))


def test_incomplete_submission_lists_missing_frames(tiny_dataset: Path, tmp_path: Path) -> None:
    (tmp_path / "preds").mkdir()
    cfg = compose_eval(
        [
            "task=depth",
            f"predictions={tmp_path / 'preds'}",
            f"data.root={tiny_dataset}",
            "data.camera.size=64",
        ],
        tmp_path / "out",
    )
    with pytest.raises(SubmissionError, match=r"\(2 problems\)") as err:
        evaluate(cfg)
    assert all("missing" in p for p in err.value.problems)
    assert not (tmp_path / "out" / "results.json").exists()


@pytest.fixture(scope="module")
def depth_onnx(tiny_exports) -> Path:
    """The session's ONNX export of :func:`depth_run` (read-only)."""
    return tiny_exports("depth")[0]


def test_onnx_export_gives_checkpoint_metrics(depth_run: Path, depth_onnx: Path, tmp_path: Path) -> None:
    onnx_path = depth_onnx
    ckpt = evaluate(
        compose_eval([f"ckpt_path={depth_run}", "num_workers=0", "num_panels=0"], tmp_path / "ckpt")
    )
    onnx = evaluate(
        compose_eval([f"onnx_path={onnx_path}", "num_workers=0", "num_panels=0"], tmp_path / "onnx")
    )
    assert onnx["model"]["source"] == "onnx" and onnx["config"]["data"] == ckpt["config"]["data"]
    # Both rows are named after the training run and say what was evaluated.
    assert onnx["model"]["run_name"] == ckpt["model"]["run_name"] == depth_run.name
    assert onnx["model"]["precision"] == "fp32"
    assert load_entry(tmp_path / "onnx" / "results.json").evaluated == "ONNX fp32"
    assert load_entry(tmp_path / "ckpt" / "results.json").evaluated.startswith("checkpoint epoch_")
    # Within the export's parity tolerance (depth relative 1e-3).
    for key, value in ckpt["metrics"].items():
        assert onnx["metrics"][key] == pytest.approx(value, rel=1e-3, abs=1e-4), key
    # Flip TTA on both paths: recorded in results.json, and the two still agree.
    ckpt_tta, onnx_tta = (
        evaluate(
            compose_eval([f"{key}={path}", "num_workers=0", "num_panels=0", "tta=flip"], tmp_path / name)
        )
        for key, path, name in (("ckpt_path", depth_run, "ckpt_tta"), ("onnx_path", onnx_path, "onnx_tta"))
    )
    for record in (ckpt_tta, onnx_tta):
        assert record["model"]["tta"] == "flip" and record["config"]["evaluation"]["tta"] == "flip"
    assert ckpt["model"]["tta"] is None and ckpt_tta["metrics"]["rmse"] != ckpt["metrics"]["rmse"]
    for key, value in ckpt_tta["metrics"].items():
        assert onnx_tta["metrics"][key] == pytest.approx(value, rel=1e-3, abs=1e-4), key
    # Which weights training started from travels through the checkpoint and the ONNX metadata.
    weights = {"encoder_weights": None, "weights_path": None}  # the quick start: random initialisation
    assert ckpt["model"]["weights"] == onnx["model"]["weights"] == weights


def test_an_onnx_model_refuses_data_of_another_size_or_lens(depth_onnx: Path, tmp_path: Path) -> None:
    onnx_path = depth_onnx
    # A fixed-size export refuses data served at another size, naming both.
    with pytest.raises(ValueError, match="takes 64x64 images but the data serves 32x32"):
        evaluate(
            compose_eval([f"onnx_path={onnx_path}", "data.camera.size=32"], tmp_path / "other"),
            ["data.camera.size=32"],
        )
    # The model carries its camera: data served through another lens of the same size is refused, naming both...
    with pytest.raises(
        ConfigError, match=r"exported for another camera .*equidistant 64x64 .*allow_camera_mismatch"
    ):
        evaluate(
            compose_eval([f"onnx_path={onnx_path}", "num_panels=0"], tmp_path / "lens"),
            ["data.camera.fov_deg=170"],
        )
    # ...unless told to score it anyway.
    allowed = evaluate(
        compose_eval(
            [f"onnx_path={onnx_path}", "num_panels=0", "allow_camera_mismatch=true"], tmp_path / "lens2"
        ),
        ["data.camera.fov_deg=170"],
    )
    assert allowed["config"]["camera"]["fov_deg"] == 170.0


def test_training_and_evaluation_agree_to_the_documented_precision(depth_run: Path, tmp_path: Path) -> None:
    """docs/evaluation.md, "Evaluate": the training run's test numbers and evaluate.py's on the same checkpoint.

    With loader workers the evaluation runs the model on fewer intra-op threads than training did, so its float32
    convolutions sum in another order: continuous metrics agree to 1e-6 relative (6 significant digits, more than
    the leaderboard prints), counted ones (δ) up to single pixels at a threshold.
    """
    trained = load_entry(depth_run / "results.json")
    cfg = compose_eval([f"ckpt_path={depth_run}", "num_workers=2", "num_panels=0"], tmp_path / "eval")
    evaluate(cfg)
    evaluated = load_entry(tmp_path / "eval" / "results.json")
    assert trained.metrics.keys() == evaluated.metrics.keys()
    for key, value in trained.metrics.items():
        tolerance = {"abs": 1e-3} if key.startswith("delta") else {"rel": 1e-6}
        assert evaluated.metrics[key] == pytest.approx(value, **tolerance), key
    # Two rows of one run on the leaderboard, told apart by what was evaluated.
    assert trained.run == evaluated.run == depth_run.name
    assert trained.evaluated.endswith("(training test)") and not evaluated.evaluated.endswith(
        "(training test)"
    )


def test_the_output_folder_is_out_as_for_the_other_commands(depth_run: Path, tmp_path: Path) -> None:
    """``out=`` names the folder (as export's, predict's and the leaderboard's); ``output_dir=``, its former name,
    still does, with a warning; the run directory Hydra made under ``logs/eval/runs`` is not left behind empty."""
    env = {"PROJECT_ROOT": str(tmp_path / "project")}
    base = [f"ckpt_path={depth_run}", "num_workers=0", "num_panels=0"]
    for key in ("out", "output_dir"):
        done = run_in_process(EVALUATE, [*base, f"{key}={tmp_path / key}"], extra_env=env)
        assert done.returncode == 0, done.stderr[-2000:]
        assert (tmp_path / key / "results.json").is_file() and (tmp_path / key / "evaluate.log").is_file()
        assert ("output_dir= is deprecated" in done.stdout + done.stderr) == (key == "output_dir")
    assert not (tmp_path / "project").exists()
