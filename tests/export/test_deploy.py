"""The deployment export command: tiny runs -> verified ONNX with metadata, int8, and its failure paths."""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import shutil
from pathlib import Path

import hydra
import lightning as L
import numpy as np
import onnx
import onnxruntime as ort
import pytest
import torch
from omegaconf import OmegaConf, open_dict

import airfisheye_bench.export.deploy as deploy
import airfisheye_bench.export.quantize as quantize
from airfisheye_bench.cli import export as export_command
from airfisheye_bench.constants import IMAGENET_MEAN, IMAGENET_STD
from airfisheye_bench.errors import OutputError
from airfisheye_bench.export import verify_onnx
from airfisheye_bench.geometry.cameras import CAMERA_MODELS, camera_from_dict
from airfisheye_bench.runs import resolve_checkpoint
from airfisheye_bench.runs.deployment import (
    COMMON_KEYS,
    KEY_WEIGHTS,
    PREFIX,
    deployment_metadata,
    parse_deployment_metadata,
    read_deployment_metadata,
    read_onnx_metadata,
)
from airfisheye_bench.specs import get_task
from airfisheye_bench.tasks.checkpoint import load_task
from airfisheye_bench.training import build
from datamodules.config import apply_data_overrides, instantiate_datamodule
from tests.helpers.commands import exit_status
from tests.helpers.configs import compose_train
from tests.helpers.random_cameras import random_cameras
from tests.helpers.runs import tiny_run_overrides

pytestmark = pytest.mark.integration  # trains, evaluates or exports: seconds per test

SIZE = 64


def task_keys(task: str) -> set[str]:
    """Every metadata key of a ``task`` model: the common keys and its spec's own."""
    return {*COMMON_KEYS, *(PREFIX + k for k in get_task(task).export.metadata)}


def _overrides(task: str, tiny_dataset: Path) -> list[str]:
    return [*tiny_run_overrides(task, tiny_dataset, SIZE), "logger=csv"]


def untrained_run(task: str, tiny_dataset: Path, run_dir: Path) -> Path:
    """A run directory with freshly initialised weights: what export needs, without the training minutes."""
    cfg = compose_train(_overrides(task, tiny_dataset))
    with open_dict(cfg):
        cfg.paths.output_dir = str(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / "config.yaml").write_text(OmegaConf.to_yaml(cfg, resolve=True))
    _, module = build(cfg)
    trainer = L.Trainer(logger=False, enable_progress_bar=False, enable_model_summary=False)
    trainer.strategy.connect(module)
    trainer.save_checkpoint(run_dir / "checkpoints" / "last.ckpt")
    return run_dir


def run_cli(args: list[str], capsys) -> tuple[int, str, str]:
    code = exit_status(export_command, args)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


class _Spy:
    """Wraps :func:`deploy.export_deployment` to keep the report the CLI printed."""

    def __init__(self) -> None:
        self.real = deploy.export_deployment
        self.report: deploy.DeploymentReport | None = None

    def __call__(self, *args, **kwargs):
        self.report = self.real(*args, **kwargs)
        return self.report


# ------------------------------------------------------------------------------------------ segmentation
@pytest.fixture(scope="module")
def seg_run(tiny_runs) -> Path:
    """The session's tiny segmentation run (read-only)."""
    return tiny_runs("seg")


@pytest.fixture(scope="module")
def seg_export(seg_run: Path, tmp_path_factory: pytest.TempPathFactory):
    """``airfisheye-export ckpt_path=<run dir> out=... quantize=dynamic`` through the CLI main."""
    out = tmp_path_factory.mktemp("seg_export") / "seg.onnx"
    record = tmp_path_factory.mktemp("seg_export_record") / "export.json"
    spy, stdout = _Spy(), io.StringIO()
    # capsys is function-scoped; this fixture is shared by the module.
    with pytest.MonkeyPatch.context() as mp, contextlib.redirect_stdout(stdout):
        mp.setattr(deploy, "export_deployment", spy)
        code = export_command(
            [f"ckpt_path={seg_run}", f"out={out}", "quantize=dynamic", "repeats=3", f"report_json={record}"]
        )
    return code, stdout.getvalue(), out, spy.report


def test_seg_export_writes_one_verified_file(seg_export) -> None:
    code, stdout, out, report = seg_export
    assert code == 0, stdout
    assert sorted(p.name for p in out.parent.iterdir()) == ["seg.int8.onnx", "seg.onnx"]  # no temporaries
    model = onnx.load(str(out), load_external_data=False)
    assert [i.name for i in model.graph.input] == ["image"]
    assert [o.name for o in model.graph.output] == ["logits"]
    dims = model.graph.input[0].type.tensor_type.shape.dim
    assert dims[0].dim_param and not dims[0].dim_value  # symbolic batch
    assert [d.dim_value for d in dims[1:]] == [3, SIZE, SIZE]  # fixed spatial size by default
    assert all(not t.HasField("data_location") or t.data_location == 0 for t in model.graph.initializer)

    assert report.parity_frames == 2  # the tiny val split has 2 frames (parity_samples=4 asked for more)
    assert report.parity.max_abs_diff <= 1e-4 and report.atol == 1e-4 and report.rtol == 0.0
    assert report.parity.latency_ratio > 0
    for text in ("max |diff|", "≤ atol 0.0001: OK", "ratio ort/torch", "int8 (dynamic)", "mIoU", "speed-up"):
        assert text in stdout
    assert stdout.index(": OK") < stdout.index(f"wrote {out}")  # the verdict, then what was written


def test_seg_export_writes_its_report_as_json(seg_export) -> None:
    code, stdout, out, report = seg_export
    path = Path(stdout.split("wrote ")[-1].strip())
    assert code == 0 and path.name == "export.json"
    record = json.loads(path.read_text(encoding="utf-8"))
    assert Path(record["onnx"]).resolve() == out.resolve() and record["onnx_bytes"] == out.stat().st_size
    assert record["parity"]["max_abs_diff"] == pytest.approx(float(report.parity.max_abs_diff))
    assert record["parity"]["verdict"].endswith(": OK") and record["parity"]["atol"] == 1e-4
    assert record["latency"]["ratio_ort_over_torch"] == pytest.approx(report.parity.latency_ratio)
    int8 = record["int8"]
    metrics = report.quantization.metrics_int8
    assert int8["ok"] and set(int8["metrics_int8"]) == set(metrics)
    for key, value in metrics.items():  # nan (a class absent from the frames) is JSON's null
        assert int8["metrics_int8"][key] == (None if value != value else pytest.approx(value)), key
    assert int8["speedup"] == pytest.approx(report.quantization.speedup)
    assert int8["int8_bytes"] == out.with_name("seg.int8.onnx").stat().st_size
    # where it comes from: the export's commit and command, the data of its frames, how the checkpoint was trained
    assert record["dataset"] == report.dataset and record["dataset"]["content_sha256"]
    source = record["provenance"]
    assert source["command"].startswith("python scripts/export_onnx.py ckpt_path=") and source["commit"]
    assert source["trained"] is None  # the tiny run has no benchmark.json or provenance.json


def test_seg_export_has_a_dynamic_batch(seg_export, seg_run: Path, tiny_dataset: Path) -> None:
    _, _, out, _ = seg_export
    task = load_task(seg_run)
    session = ort.InferenceSession(str(out), providers=["CPUExecutionProvider"])
    for batch in (1, 3):
        image = torch.randn(batch, 3, SIZE, SIZE, generator=torch.Generator().manual_seed(batch))
        (logits,) = session.run(["logits"], {"image": image.numpy()})
        assert logits.shape == (batch, len(task.class_names), SIZE, SIZE)
    report = verify_onnx(out, task.net, {"image": image}, atol=1e-4, rtol=0, measure_latency=False)
    assert report.output_shape == (3, len(task.class_names), SIZE, SIZE)


def test_seg_metadata_round_trip(seg_export, seg_run: Path) -> None:
    _, _, out, _ = seg_export
    props = read_onnx_metadata(out)
    assert set(props) == {*task_keys("seg"), KEY_WEIGHTS}
    assert all(isinstance(v, str) for v in props.values())
    meta = read_deployment_metadata(out)
    task = load_task(seg_run)
    assert meta["format_version"] == "1" and meta["task"] == "seg" and meta["model"] == "deeplabv3plus"
    assert meta["model_config"] == dict(task.hparams["model"])
    assert meta["weights"] == task.hparams["weights"] == {"encoder_weights": None, "weights_path": None}
    assert meta["inputs"] == ["image"] and meta["output"] == "logits"
    assert meta["normalization"] == {"mean": list(IMAGENET_MEAN), "std": list(IMAGENET_STD)}
    assert meta["class_names"] == task.class_names and len(meta["palette"]) == len(task.class_names)
    assert meta["ignore_index"] == 255 and meta["image_size"] == [SIZE, SIZE]
    assert meta["camera"]["width"] == SIZE and meta["camera"]["model"] == "equidistant"
    checkpoint = Path(meta["source_checkpoint"])
    assert checkpoint.is_file() and checkpoint.is_relative_to(seg_run.resolve())
    assert meta["checkpoint_sha256"] == hashlib.sha256(checkpoint.read_bytes()).hexdigest()
    # The data config rebuilds the served camera of the export.
    datamodule = hydra.utils.instantiate(OmegaConf.create(meta["data_config"]))
    datamodule.setup("validate")
    assert datamodule.camera.to_dict() == meta["camera"]
    # The int8 model carries the same metadata.
    assert read_onnx_metadata(out.with_name("seg.int8.onnx")) == props


def test_seg_dynamic_quantization_report(seg_export) -> None:
    _, _, out, report = seg_export
    q = report.quantization
    assert q is not None and q.ok and q.mode == "dynamic" and q.path == out.with_name("seg.int8.onnx")
    assert q.frames == 2 and q.int8_bytes < q.fp32_bytes
    assert {"mIoU", "pixel_acc"} <= set(q.metrics_fp32) and set(q.metrics_fp32) == set(q.metrics_int8)
    assert q.fp32_ms > 0 and q.int8_ms > 0 and q.speedup == pytest.approx(q.fp32_ms / q.int8_ms)
    assert "mIoU" in q.metric_deltas
    # Evaluation tells the two apart by their graphs (their metadata is the same).
    from airfisheye_bench.evaluation.predictors import onnx_precision

    assert (onnx_precision(out), onnx_precision(q.path)) == ("fp32", "int8")


def test_parity_failure_leaves_nothing_at_out(
    seg_export, seg_run: Path, tmp_path: Path, monkeypatch, capsys
) -> None:
    _, _, exported, _ = seg_export
    real_verify = deploy.verify_onnx

    class Shifted(torch.nn.Module):  # the graph is "corrupted": PyTorch and ONNX disagree by 1e-3
        def __init__(self, net):
            super().__init__()
            self.net = net

        def forward(self, image):
            return self.net(image) + 1e-3

    # The export itself is tested above; reuse its file to keep this test fast.
    monkeypatch.setattr(deploy, "_export", lambda task, example, path, *args: shutil.copy(exported, path))
    monkeypatch.setattr(
        deploy, "verify_onnx", lambda path, model, *a, **k: real_verify(path, Shifted(model), *a, **k)
    )
    out = tmp_path / "seg.onnx"
    code, _, err = run_cli([f"ckpt_path={seg_run}", f"out={out}", "repeats=1"], capsys)
    assert code == 1
    assert "parity check failed" in err and str(out) in err and "max abs diff 0.001" in err
    assert list(tmp_path.iterdir()) == []  # neither out nor a temporary


# --------------------------------------------------------------------------------- depth and completion
@pytest.fixture(scope="module", params=["depth", "completion"])
def depth_export(request: pytest.FixtureRequest, tiny_exports) -> tuple[str, Path, int, str]:
    """``(task, onnx path, exit status, printed report)``: the session's export of each depth task's tiny run, taken
    as set-up (its training and export are shared with the evaluate and predict tests)."""
    return request.param, *tiny_exports(request.param)


def test_depth_tasks_export_through_the_cli(depth_export: tuple[str, Path, int, str]) -> None:
    """The session's export of each tiny run (``airfisheye-export ckpt_path=<run>/checkpoints/last.ckpt``)."""
    task, out, code, stdout = depth_export
    assert code == 0, stdout
    assert "|diff| ≤ atol 0.0001 + rtol 0.001 × |torch| everywhere" in stdout and "ratio ort/torch" in stdout
    assert stdout.index(": OK") < stdout.index("wrote ")
    names = ["image", "sparse_depth"] if task == "completion" else ["image"]
    session = ort.InferenceSession(str(out), providers=["CPUExecutionProvider"])
    assert [i.name for i in session.get_inputs()] == names
    assert [o.name for o in session.get_outputs()] == ["depth"]
    for batch in (1, 3):
        feed = {"image": np.random.default_rng(batch).standard_normal((batch, 3, SIZE, SIZE), np.float32)}
        if task == "completion":
            feed["sparse_depth"] = np.zeros((batch, 1, SIZE, SIZE), np.float32)
        assert session.run(["depth"], feed)[0].shape == (batch, 1, SIZE, SIZE)
    meta = read_deployment_metadata(out)
    assert set(read_onnx_metadata(out)) == {*task_keys(task), KEY_WEIGHTS}
    assert meta["output"] == "depth" and meta["inputs"] == names and meta["max_depth"] == 120.0
    assert meta["min_depth"] == (1e-3 if task == "depth" else 1e-4)
    if task == "completion":
        assert meta["occlusion"] == "ordering"


# ------------------------------------------------------------------------------------------ bad inputs
def test_missing_checkpoint_is_a_clear_error(tmp_path: Path, capsys) -> None:
    out = tmp_path / "m.onnx"
    code, _, err = run_cli([f"ckpt_path={tmp_path / 'nope'}", f"out={out}"], capsys)
    assert code == 2 and "nope" in err and "does not exist" in err
    assert not out.exists()


def test_corrupt_checkpoint_is_a_clear_error(seg_run: Path, tmp_path: Path, capsys) -> None:
    run = tmp_path / "run"
    (run / "checkpoints").mkdir(parents=True)
    shutil.copy(seg_run / "config.yaml", run / "config.yaml")
    (run / "checkpoints" / "last.ckpt").write_bytes(b"not a checkpoint")
    code, _, err = run_cli([f"ckpt_path={run}", f"out={tmp_path / 'c.onnx'}"], capsys)
    assert code == 2 and "last.ckpt" in err and "not a readable checkpoint" in err
    assert not (tmp_path / "c.onnx").exists()


def test_checkpoint_without_run_config_is_a_clear_error(seg_run: Path, tmp_path: Path, capsys) -> None:
    lonely = tmp_path / "a" / "b" / "model.ckpt"
    lonely.parent.mkdir(parents=True)
    shutil.copy(seg_run / "checkpoints" / "last.ckpt", lonely)
    code, _, err = run_cli([f"ckpt_path={lonely}", f"out={tmp_path / 'x.onnx'}"], capsys)
    assert code == 2 and "config.yaml" in err and "model.ckpt" in err


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["out=x.onnx"], "ckpt_path= is required"),
        (["ckpt_path=r", "out=x.onnx", "colour=red"], "unknown option 'colour'"),
        (["ckpt_path=r", "out=x.onnx", "batch=two"], "batch=two: expected an integer"),
        (["ckpt_path=r", "out=x.onnx", "dynamic_spatial=maybe"], "dynamic_spatial=maybe: expected a boolean"),
        (["ckpt_path=r", "out=x.onnx", "quantize"], "key=value"),
        (["ckpt_path=r", "out=x.onnx", "data.camera.size=1,2"], "a comma list is a sweep"),
    ],
)
def test_bad_arguments_are_one_line_naming_the_key(args: list[str], message: str, capsys) -> None:
    code, _, err = run_cli(args, capsys)
    assert code == 2 and err.startswith("error: ") and message in err and len(err.splitlines()) == 1


def test_bad_values_and_overrides_are_rejected(seg_run: Path, tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="quantize must be one of"):
        deploy.export_deployment(seg_run, tmp_path / "x.onnx", quantize="fp16")
    with pytest.raises(ValueError, match="batch must be >= 2"):
        deploy.export_deployment(seg_run, tmp_path / "x.onnx", batch=1)
    with pytest.raises(ValueError, match=r"unknown override data\.colour"):
        deploy.export_deployment(seg_run, tmp_path / "x.onnx", data_overrides={"colour": 1})
    with pytest.raises(OutputError, match="is a folder"):
        deploy.export_deployment(seg_run, tmp_path)
    with pytest.raises(ValueError, match="task=seg model"):
        deploy.export_deployment(seg_run, tmp_path / "x.onnx", data_overrides={"task": "depth"})
    assert list(tmp_path.iterdir()) == []


def test_failed_quantization_keeps_the_fp32_model(
    seg_export, seg_run: Path, tmp_path: Path, monkeypatch
) -> None:
    _, _, exported, _ = seg_export
    fp32 = tmp_path / "seg.onnx"
    shutil.copy(exported, fp32)
    stale = tmp_path / "seg.int8.onnx"
    stale.write_bytes(b"int8 of an older export")

    def unsupported(*args, **kwargs):
        raise RuntimeError("no int8 kernel for DeformConv")

    monkeypatch.setattr(quantize, "_run_quantizer", unsupported)
    task = load_task(seg_run)
    data = apply_data_overrides(deploy._run_data(resolve_checkpoint(seg_run)), task="seg")
    datamodule = instantiate_datamodule(data, "validate")
    workdir = tmp_path / "work"
    workdir.mkdir()
    image = torch.zeros(2, 3, SIZE, SIZE)
    report = quantize.quantize_model(fp32, "static", task, datamodule, {"image": image}, workdir, 2, 0, 1)
    assert not report.ok and report.path is None
    assert "static int8 quantisation of deeplabv3plus failed" in report.error and "DeformConv" in report.error
    assert fp32.is_file() and not stale.exists()
    assert "FAILED" in "\n".join(quantize.quantization_lines(report, "seg"))


def test_failed_quantization_exits_with_code_3(monkeypatch, capsys) -> None:
    failed = deploy.QuantizationReport(
        mode="dynamic", error="dynamic int8 quantisation of nlspn failed (...)"
    )

    class Report:
        quantization = failed

        def summary(self) -> str:
            return "int8: FAILED"

    monkeypatch.setattr(deploy, "export_deployment", lambda **kwargs: Report())
    code, stdout, _ = run_cli(["ckpt_path=r", "out=x.onnx", "quantize=dynamic"], capsys)
    assert code == 3 and "FAILED" in stdout


# ------------------------------------------------------------------------------------- metadata contract
def _depth_meta(**changes):
    task = changes.pop("task", "depth")
    kwargs = dict(
        task=task,
        model="adabins",
        model_config={"name": "adabins"},
        normalization={"mean": IMAGENET_MEAN, "std": IMAGENET_STD},
        camera={"model": "equidistant", "width": 32, "height": 24, "fov_deg": 190.0},
        data_config={"task": "depth"},
        checkpoint_sha256="ab" * 32,
        source_checkpoint="run/last.ckpt",
        min_depth=1e-3,
        max_depth=120.0,
    )
    kwargs.update(changes)
    return deployment_metadata(**kwargs)


def test_metadata_encodes_exactly_the_task_keys() -> None:
    meta = _depth_meta()
    assert set(meta) == task_keys("depth")
    assert json.loads(meta["airfisheye.image_size"]) == [24, 32]
    decoded = parse_deployment_metadata({**meta, "other.key": "ignored"})
    assert decoded["camera"]["fov_deg"] == 190.0 and decoded["min_depth"] == 1e-3
    assert "other.key" not in decoded and "key" not in decoded


@pytest.mark.parametrize("family", sorted(CAMERA_MODELS))
def test_metadata_carries_every_camera_model(family: str) -> None:
    """The served camera of any model goes into the metadata and comes back the same camera."""
    camera = random_cameras(family, 1)[0]
    decoded = parse_deployment_metadata(_depth_meta(camera=camera.to_dict()))
    assert decoded["image_size"] == [camera.height, camera.width]
    assert camera_from_dict(decoded["camera"]) == camera


def test_metadata_rejects_wrong_task_fields() -> None:
    with pytest.raises(ValueError, match="needs class_names, palette, ignore_index"):
        _depth_meta(task="seg", min_depth=None, max_depth=None)
    with pytest.raises(ValueError, match="takes no occlusion"):
        _depth_meta(occlusion="ordering")
    with pytest.raises(ValueError, match="needs occlusion"):
        _depth_meta(task="completion")


def test_parse_names_the_bad_key() -> None:
    meta = _depth_meta()
    with pytest.raises(ValueError, match=r"no airfisheye\.format_version"):
        parse_deployment_metadata({})
    with pytest.raises(ValueError, match=r"airfisheye\.max_depth is not valid JSON"):
        parse_deployment_metadata({**meta, "airfisheye.max_depth": "12 m"})
    del meta["airfisheye.camera"]
    with pytest.raises(ValueError, match=r"lacks \['airfisheye.camera'\]"):
        parse_deployment_metadata(meta)


def test_read_names_the_file(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match=r"missing\.onnx"):
        read_deployment_metadata(tmp_path / "missing.onnx")


# ---------------------------------------------------------------------------------------------- slow
@pytest.mark.slow
def test_seg_dynamic_spatial_and_static_quantization(seg_run: Path, tmp_path: Path) -> None:
    out = tmp_path / "seg.onnx"
    report = deploy.export_deployment(seg_run, out, dynamic_spatial=True, quantize="static", repeats=2)
    assert report.dynamic_spatial and report.quantization.ok
    from airfisheye_bench.evaluation.predictors import onnx_precision

    assert onnx_precision(report.quantization.path) == "int8"  # QLinearConv / QuantizeLinear
    session = ort.InferenceSession(str(out), providers=["CPUExecutionProvider"])
    (logits,) = session.run(["logits"], {"image": np.zeros((2, 3, 96, 96), np.float32)})
    assert logits.shape[-2:] == (96, 96)


@pytest.mark.slow
@pytest.mark.parametrize("mode", ["dynamic", "static"])
def test_nlspn_quantization_is_reported_not_raised(mode: str, tiny_dataset: Path, tmp_path: Path) -> None:
    run = untrained_run("completion", tiny_dataset, tmp_path / "run")
    report = deploy.export_deployment(run, tmp_path / "c.onnx", quantize=mode, repeats=1)
    q = report.quantization
    assert (tmp_path / "c.onnx").is_file()
    assert q.ok or ("nlspn" in q.error and not (tmp_path / "c.int8.onnx").exists())
    if q.ok:
        assert {"rmse", "mae", "abs_rel", "delta1"} <= set(q.metrics_int8)
