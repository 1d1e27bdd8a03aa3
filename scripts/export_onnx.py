"""Export a trained run to a verified ONNX file (the same as ``airfisheye-export``; ``--help`` lists the options).

python scripts/export_onnx.py ckpt_path=<ckpt or run dir> out=model.onnx [dynamic_spatial=false] [batch=2]
    [parity_samples=4] [quantize=none|dynamic|static] [opset=20] [data.<key>=<value> ...]
"""

import sys

from airfisheye_bench.cli.commands import export

if __name__ == "__main__":
    sys.exit(export())
