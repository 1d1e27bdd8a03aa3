"""Prediction folders: every problem reported together, nothing unpickled, no path escapes, atomic writing."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image

from airfisheye_bench.evaluation import (
    SubmissionError,
    SubmissionWriter,
    read_prediction,
    validate_submission,
    write_prediction,
    write_submission,
)
from airfisheye_bench.specs import get_task

IDS = ["env/traj/000000", "env/traj/000001", "other/traj/000002"]
SHAPE = (6, 8)


def _depth(seed: int) -> np.ndarray:
    return np.random.default_rng(seed).uniform(0.5, 130.0, SHAPE).astype(np.float32)


@pytest.mark.parametrize("fmt", ["png", "npy"])
def test_depth_round_trip(tmp_path: Path, fmt: str) -> None:
    depth = _depth(0)
    depth[0, 0] = 0.0  # no prediction
    root = write_submission(tmp_path / "sub", "depth", [(IDS[0], depth)], depth_format=fmt)
    files = validate_submission(root, "depth", IDS[:1], SHAPE)
    back = read_prediction(files[IDS[0]], "depth")
    assert back.shape == (1, *SHAPE) and back.dtype == torch.float32
    # 16-bit PNG stores round(range * 256): at most half a step of error; npy is exact.
    tol = 0.5 / 256 + 1e-6 if fmt == "png" else 0.0
    assert np.abs(back[0].numpy() - depth).max() <= tol
    assert back[0, 0, 0] == 0.0


@pytest.mark.parametrize("fmt", ["png", "npy"])
@pytest.mark.parametrize("task", ["depth", "completion"])
def test_saved_non_finite_outputs_score_as_the_model_output(tmp_path: Path, task: str, fmt: str) -> None:
    """A model that outputs NaN or +-inf (an fp16 overflow): its saved files are valid and score as it did.

    The metrics map +inf to max_depth and NaN to "no prediction"; the files hold finite values only.
    """
    depth = np.round(_depth(1) * 256) / 256  # on the PNG grid: the comparison is exact
    depth[0, :4] = [np.inf, np.nan, -np.inf, 0.0]
    target = torch.from_numpy(_depth(2))[None, None]
    root = write_submission(tmp_path / "sub", task, [(IDS[0], depth)], depth_format=fmt)
    saved = read_prediction(validate_submission(root, task, IDS[:1], SHAPE)[IDS[0]], task)
    scores = []
    for prediction in (torch.from_numpy(depth)[None, None], saved[None]):
        metric = get_task(task).make_metric()
        metric.update(prediction, target)
        scores.append({k: float(v) for k, v in metric.compute().items()})
    assert scores[0] == scores[1]


def test_labels_round_trip(tmp_path: Path) -> None:
    labels = np.random.default_rng(1).integers(0, 13, SHAPE).astype(np.uint8)
    labels[0] = 255
    root = write_submission(tmp_path / "sub", "seg", [(i, labels) for i in IDS])
    files = validate_submission(root, "seg", IDS, SHAPE)
    assert sorted(files) == sorted(IDS)
    back = read_prediction(files[IDS[2]], "seg")
    assert back.dtype == torch.int64 and torch.equal(back, torch.from_numpy(labels.astype(np.int64)))


def test_every_problem_listed_at_once(tmp_path: Path) -> None:
    root = tmp_path / "sub"
    write_prediction(root / f"{IDS[0]}.npy", np.zeros((5, 8), np.float32), "depth")  # wrong size
    np.save(root / "env/traj/000001.npy", np.zeros(SHAPE, np.float64))  # wrong dtype
    write_prediction(root / "env/traj/999999.png", np.zeros(SHAPE), "depth")  # extra
    (root / ".DS_Store").write_bytes(b"ignored")  # hidden files are not reported
    with pytest.raises(SubmissionError) as err:
        validate_submission(root, "depth", IDS, SHAPE)
    problems = err.value.problems
    assert len(problems) == 4, problems
    text = str(err.value)
    assert "env/traj/000000.npy: shape (5, 8)" in text
    assert "env/traj/000001.npy: dtype float64" in text
    assert "other/traj/000002: missing" in text
    assert "env/traj/999999.png: extra file" in text


def test_non_finite_predictions_named_with_their_counts(tmp_path: Path) -> None:
    root = tmp_path / "sub"
    nan, inf, fine = _depth(0), _depth(1), _depth(2)
    nan[0, :3] = np.nan
    inf[1, 1], inf[2, 2] = np.inf, -np.inf
    for sample_id, depth in zip(IDS, (nan, inf, fine), strict=True):
        (root / sample_id).parent.mkdir(parents=True, exist_ok=True)
        np.save(root / f"{sample_id}.npy", depth)
    with pytest.raises(SubmissionError, match=r"\(2 problems\)") as err:
        validate_submission(root, "depth", IDS, SHAPE)
    size = nan.size
    assert err.value.problems == [
        f"{IDS[0]}.npy: 3 of {size} values are not finite (3 NaN, 0 infinite); write 0 where there is no prediction",
        f"{IDS[1]}.npy: 2 of {size} values are not finite (0 NaN, 2 infinite); write 0 where there is no prediction",
    ]


def test_truncated_npy_body_is_named(tmp_path: Path) -> None:
    path = tmp_path / "sub" / f"{IDS[0]}.npy"
    write_prediction(path, _depth(0), "depth")
    path.write_bytes(path.read_bytes()[:-10])
    with pytest.raises(SubmissionError, match=r"000000\.npy: not a readable \.npy file"):
        validate_submission(tmp_path / "sub", "depth", IDS[:1], SHAPE)


def test_wrong_png_types(tmp_path: Path) -> None:
    root = tmp_path / "sub"
    (root / "env/traj").mkdir(parents=True)
    Image.fromarray(np.zeros((*SHAPE, 3), np.uint8)).save(root / "env/traj/000000.png")  # RGB labels
    Image.fromarray(np.zeros(SHAPE, np.uint8)).save(
        root / "env/traj/000001.png", format="JPEG"
    )  # JPEG as .png
    (root / "env/traj/000002.png").write_bytes(b"not a png")
    with pytest.raises(SubmissionError) as err:
        validate_submission(root, "seg", [*IDS[:2], "env/traj/000002"], SHAPE)
    text = str(err.value)
    assert "000000.png: PNG mode RGB, expected a 8-bit single-channel label PNG" in text
    assert "000001.png: is a JPEG file, expected PNG" in text
    assert "000002.png: not a readable PNG" in text


def test_depth_png_must_be_16_bit(tmp_path: Path) -> None:
    root = tmp_path / "sub"
    (root / "env/traj").mkdir(parents=True)
    Image.fromarray(np.zeros(SHAPE, np.uint8)).save(root / "env/traj/000000.png")
    with pytest.raises(SubmissionError, match="expected a 16-bit depth"):
        validate_submission(root, "depth", IDS[:1], SHAPE)


def test_ambiguous_png_and_npy(tmp_path: Path) -> None:
    root = write_submission(tmp_path / "sub", "depth", [(IDS[0], _depth(0))], depth_format="png")
    write_prediction(root / f"{IDS[0]}.npy", _depth(0), "depth")
    with pytest.raises(
        SubmissionError, match=r"ambiguous, both env/traj/000000\.png and env/traj/000000\.npy"
    ):
        validate_submission(root, "depth", IDS[:1], SHAPE)


def test_pickled_npy_is_rejected_unread(tmp_path: Path) -> None:
    root = tmp_path / "sub"
    (root / "env/traj").mkdir(parents=True)
    np.save(root / f"{IDS[0]}.npy", np.array([{"x": 1}], dtype=object), allow_pickle=True)
    with pytest.raises(SubmissionError, match="dtype object"):
        validate_submission(root, "depth", IDS[:1], SHAPE)


@pytest.mark.skipif(os.name == "nt", reason="symlinks")
def test_links_cannot_escape(tmp_path: Path) -> None:
    outside = tmp_path / "secret.npy"
    np.save(outside, _depth(0))
    root = tmp_path / "sub"
    (root / "env/traj").mkdir(parents=True)
    (root / f"{IDS[0]}.npy").symlink_to(outside)
    (root / f"{IDS[1]}.npy").symlink_to(tmp_path / "missing.npy")
    with pytest.raises(SubmissionError) as err:
        validate_submission(root, "depth", IDS[:2], SHAPE)
    text = str(err.value)
    assert "env/traj/000000.npy: leads outside the prediction folder" in text
    assert "env/traj/000001.npy: broken link" in text


def test_id_with_dotdot_cannot_escape(tmp_path: Path) -> None:
    root = tmp_path / "sub"
    root.mkdir()
    np.save(tmp_path / "escape.npy", _depth(0))
    with pytest.raises(SubmissionError, match="leads outside"):
        validate_submission(root, "depth", ["../escape"], SHAPE)


def test_missing_folder_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match=r"prediction folder .*nope does not exist"):
        validate_submission(tmp_path / "nope", "seg", IDS, SHAPE)


def test_writer_leaves_nothing_on_failure(tmp_path: Path) -> None:
    root = tmp_path / "sub"
    with pytest.raises(RuntimeError, match="boom"), SubmissionWriter(root, "depth") as writer:
        writer.add(IDS[0], _depth(0))
        raise RuntimeError("boom")
    assert not root.exists() and list(tmp_path.iterdir()) == []


def test_writer_refuses_existing_folder(tmp_path: Path) -> None:
    with pytest.raises(FileExistsError, match="already exists"):
        SubmissionWriter(tmp_path, "seg")


def test_labels_out_of_range_rejected(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"0\.\.255"):
        write_prediction(tmp_path / "a.png", np.full(SHAPE, 300), "seg")
