"""``logger=mlflow``: a run logged to a real ``mlflow server`` on the loopback interface, read back through MLflow's
client; evaluation and export log to the same run (``mlflow_run=auto``). The tests that log are skipped when mlflow
is not installed (``pip install -e ".[mlflow]"``)."""

from __future__ import annotations

import importlib.util
import json
import os
import socket
import subprocess
import sys
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import pytest

from airfisheye_bench.tracking import RUN_RECORD, choose_store, local_store, read_run_record
from tests.helpers.runs import tiny_run_overrides

# No network in tests: MLflow 3 sends usage telemetry unless told not to (inherited by the commands and the server).
os.environ["MLFLOW_DISABLE_TELEMETRY"] = "true"
needs_mlflow = pytest.mark.skipif(
    importlib.util.find_spec("mlflow") is None, reason='the mlflow extra: pip install -e ".[mlflow]"'
)

ROOT = Path(__file__).resolve().parents[2]
SERVER_START_S = 120  # a cold `mlflow server` imports for seconds, then migrates its SQLite store


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def mlflow_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """``mlflow server`` on 127.0.0.1 at a free port (SQLite store, served artifacts), stopped after the module."""
    folder = tmp_path_factory.mktemp("mlflow_server")
    port = _free_port()
    uri = f"http://127.0.0.1:{port}"
    log = (folder / "server.log").open("w")
    server = subprocess.Popen(
        [sys.executable, "-m", "mlflow", "server", "--host", "127.0.0.1", "--port", str(port),
         "--backend-store-uri", f"sqlite:///{folder / 'mlflow.db'}",
         "--artifacts-destination", str(folder / "artifacts"), "--workers", "1"],
        stdout=log, stderr=subprocess.STDOUT, cwd=folder,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + SERVER_START_S
        while True:
            assert server.poll() is None, (folder / "server.log").read_text()[-3000:]
            try:
                with urllib.request.urlopen(f"{uri}/health", timeout=2) as answer:
                    if answer.status == 200:
                        break
            except OSError:
                pass
            assert time.monotonic() < deadline, (folder / "server.log").read_text()[-3000:]
            time.sleep(0.5)
        yield uri
    finally:
        server.terminate()
        try:
            server.wait(timeout=20)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait()
        log.close()


def _run(script: str, args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ("HYDRA_FULL_ERROR", "MLFLOW_TRACKING_URI")}
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    done = subprocess.run(
        [sys.executable, str(ROOT / script), *args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, f"{script} {args}:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    return done


def _client(tracking_uri: str):
    from mlflow.tracking import MlflowClient  # the optional extra, imported by the tests that log only

    return MlflowClient(tracking_uri=tracking_uri)


def _artifacts(client, run_id: str, path: str | None = None) -> set[str]:
    found: set[str] = set()
    for item in client.list_artifacts(run_id, path):
        found |= _artifacts(client, run_id, item.path) if item.is_dir else {item.path}
    return found


@needs_mlflow
@pytest.mark.slow
def test_a_run_logged_to_a_server_is_read_back(
    mlflow_server: str, tiny_dataset: Path, tmp_path: Path
) -> None:
    run_dir = tmp_path / "run"
    overrides = [*tiny_run_overrides("seg", tiny_dataset), "logger=mlflow", f"hydra.run.dir={run_dir}"]
    _run("train.py", [*overrides, f"logger.mlflow.tracking_uri={mlflow_server}"], tmp_path)

    record = read_run_record(run_dir)
    assert record is not None and record["tracking_uri"] == mlflow_server
    results = json.loads((run_dir / "results.json").read_text())
    client = _client(mlflow_server)
    run = client.get_run(record["run_id"])
    assert run.info.status == "FINISHED" and run.info.run_name == "run"
    assert client.get_experiment(run.info.experiment_id).name == "airfisheye-seg"
    # The resolved config as parameters (dotted keys), next to the module's own hyper-parameters.
    params = run.data.params
    assert params["task.name"] == "seg" and params["data.camera.size"] == "64"
    assert float(params["task.module.optimizer.lr"]) == 0.02
    assert params["paths.output_dir"] == str(run_dir)
    # Every metric: training, validation and test; the test scores are results.json's.
    metrics = run.data.metrics
    assert {"train/loss", "val/mIoU", "epoch"} <= set(metrics)
    assert metrics["test/mIoU"] == pytest.approx(results["metrics"]["mIoU"])
    history = client.get_metric_history(run.info.run_id, "val/mIoU")
    assert len(history) == 1  # trainer=debug: one epoch
    # results.json, config.yaml and the panels as artifacts; the best checkpoint's path as a tag.
    artifacts = _artifacts(client, run.info.run_id)
    panels = {f"panels/{p.name}" for p in (run_dir / "panels").glob("*.png")}
    assert panels and {"results.json", "config.yaml", *panels} <= artifacts
    served = Path(client.download_artifacts(run.info.run_id, "results.json", str(tmp_path)))
    assert json.loads(served.read_text()) == results
    assert run.data.tags["best_checkpoint"] == results["model"]["checkpoint"]
    assert Path(run.data.tags["best_checkpoint"]).is_file()

    # Evaluation and export log into the same run.
    eval_dir = tmp_path / "eval"
    _run(
        "scripts/evaluate.py",
        [f"ckpt_path={run_dir}", "mlflow_run=auto", f"hydra.run.dir={eval_dir}"],
        tmp_path,
    )
    onnx = tmp_path / "seg.onnx"
    _run(
        "scripts/export_onnx.py",
        [f"ckpt_path={run_dir}", f"out={onnx}", "repeats=1", "mlflow_run=auto"],
        tmp_path,
    )
    run = client.get_run(record["run_id"])
    evaluated = json.loads((eval_dir / "results.json").read_text())
    assert run.data.metrics["evaluate/checkpoint/test/mIoU"] == pytest.approx(evaluated["metrics"]["mIoU"])
    assert run.data.metrics["export/parity_max_abs_diff"] >= 0
    assert run.data.tags["onnx_path"] == str(onnx)
    artifacts = _artifacts(client, run.info.run_id)
    assert {"evaluate/checkpoint/test/results.json", "export/seg.onnx"} <= artifacts
    assert any(a.startswith("evaluate/checkpoint/test/panels/") for a in artifacts)
    assert client.get_experiment_by_name("airfisheye-seg").experiment_id == run.info.experiment_id


def test_each_job_of_a_multirun_logs_to_its_own_store(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """MLflow puts the store in use into $MLFLOW_TRACKING_URI: the next job in the process keeps its own store, while
    a store the user set there is still the one used (what :class:`RunMLFlowLogger` logs to)."""
    monkeypatch.delenv("MLFLOW_TRACKING_URI", raising=False)
    first = choose_store(tmp_path / "0")
    assert first == local_store(tmp_path / "0")
    monkeypatch.setenv("MLFLOW_TRACKING_URI", first[0])  # what mlflow.set_tracking_uri does
    assert choose_store(tmp_path / "1") == local_store(tmp_path / "1")
    chosen = f"sqlite:///{tmp_path / 'shared.db'}"
    monkeypatch.setenv("MLFLOW_TRACKING_URI", chosen)
    assert choose_store(tmp_path / "2") == (chosen, None)
    assert choose_store(tmp_path / "3", artifact_location="s3://bucket/a") == (chosen, "s3://bucket/a")
    assert choose_store(tmp_path / "4", "http://127.0.0.1:5000") == ("http://127.0.0.1:5000", None)


@needs_mlflow
@pytest.mark.slow
def test_the_default_store_is_under_the_run_directory(tiny_dataset: Path, tmp_path: Path) -> None:
    """Without a tracking URI the run logs to its own SQLite store; a resume continues that MLflow run."""
    run_dir = tmp_path / "run"
    overrides = [*tiny_run_overrides("seg", tiny_dataset), "logger=mlflow", f"hydra.run.dir={run_dir}"]
    _run("train.py", overrides, tmp_path)
    record = read_run_record(run_dir)
    uri, artifacts = local_store(run_dir)
    assert record is not None and record["tracking_uri"] == uri
    assert (run_dir / "mlflow" / "mlflow.db").is_file() and not (tmp_path / "mlruns").exists()
    client = _client(uri)
    run = client.get_run(record["run_id"])
    stored = Path(run.info.artifact_uri.removeprefix("file://"))
    assert stored.is_relative_to(artifacts) and (stored / "results.json").is_file()
    assert (run_dir / "metrics.csv").is_file()  # the CSV log stays, next to MLflow
    # A resume (one more epoch: the run's own configuration and the one key given) continues the same MLflow run:
    # the validation history grows.
    _run("train.py", ["ckpt_path=last", f"hydra.run.dir={run_dir}", "trainer.max_epochs=2"], tmp_path)
    assert read_run_record(run_dir)["run_id"] == record["run_id"]
    assert len(client.get_metric_history(record["run_id"], "val/mIoU")) == 2
    assert RUN_RECORD in {p.name for p in run_dir.iterdir()}
