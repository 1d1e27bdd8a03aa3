"""Model export: ONNX with named inputs/outputs and metadata, checked against PyTorch in ONNX Runtime."""

from airfisheye_bench.export.onnx import (
    OnnxParityError,
    ParityReport,
    export_onnx,
    verify_onnx,
)

__all__ = ["OnnxParityError", "ParityReport", "export_onnx", "verify_onnx"]
