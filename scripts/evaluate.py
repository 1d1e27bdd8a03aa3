"""``python scripts/evaluate.py ckpt_path=... | onnx_path=... | task=... predictions=DIR [split=test]``.

Scores a checkpoint, an exported ONNX model or a folder of prediction files on a split with the paper's metrics,
writes ``results.json`` (the leaderboard format) and qualitative panels, and prints the table. The same as
``airfisheye-evaluate`` (:func:`airfisheye_bench.cli.apps.evaluate`); see ``configs/evaluate.yaml`` (or
``--help``) for every option and :mod:`airfisheye_bench.evaluation.command` for the details.
"""

from airfisheye_bench.cli.apps import evaluate

if __name__ == "__main__":
    evaluate()
