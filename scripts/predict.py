"""Run a trained model on your own footage (the same as ``airfisheye-predict``; ``--help`` lists the options).

python scripts/predict.py ckpt_path=<run dir, .ckpt or .onnx> input=<folder of images or video> [out=DIR]
    [input_format=fisheye|erp] [camera=<calibration file>] [allow_camera_mismatch=false] [sparse=<folder>]
    [depth_format=png16|npy]
"""

import sys

from airfisheye_bench.cli.commands import predict

if __name__ == "__main__":
    sys.exit(predict())
