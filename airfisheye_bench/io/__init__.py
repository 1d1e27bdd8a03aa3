"""Reading and writing the on-disk AirFisheye layout (``docs/design.md``), for synthetic and real releases alike,
the calibration files of other tools (:func:`load_camera`, ``docs/design.md`` "Calibration files") and LiDAR scan
files (:func:`load_scan`, ``docs/design.md`` "Scan files and filtering").

This package is the one place that knows file names and encodings; the generator writes through it and the
datamodules read through it (:class:`DatasetReader`).
"""

from airfisheye_bench.io.calib_yaml import Calibration
from airfisheye_bench.io.calibration_files import load_camera, read_calibration, save_camera
from airfisheye_bench.io.codecs import (
    read_depth,
    read_label,
    read_lidar,
    read_pfm,
    read_rgb,
    read_visibility,
    write_depth,
    write_label,
    write_lidar,
    write_pfm,
    write_rgb,
    write_visibility,
)
from airfisheye_bench.io.dataset_spec import (
    DATASET_YAML,
    ClassDef,
    DatasetSpec,
    FileEncodings,
    SplitsSpec,
    classes_from,
)
from airfisheye_bench.io.datasets import DatasetSource
from airfisheye_bench.io.datasets.airfisheye import DatasetReader
from airfisheye_bench.io.errors import CalibrationFileError, DatasetFormatError, EmptySplitError
from airfisheye_bench.io.layout import MODALITIES, DatasetLayout, trajectory_of
from airfisheye_bench.io.poses import ImuTable, PoseTable, camera_from_lidar
from airfisheye_bench.io.scan import Scan, load_scan
from airfisheye_bench.io.splits import parse_sample_id, read_split, write_split

__all__ = [
    "DATASET_YAML",
    "MODALITIES",
    "Calibration",
    "CalibrationFileError",
    "ClassDef",
    "DatasetFormatError",
    "DatasetLayout",
    "DatasetReader",
    "DatasetSource",
    "DatasetSpec",
    "EmptySplitError",
    "FileEncodings",
    "ImuTable",
    "PoseTable",
    "Scan",
    "SplitsSpec",
    "camera_from_lidar",
    "classes_from",
    "load_camera",
    "load_scan",
    "parse_sample_id",
    "read_calibration",
    "read_depth",
    "read_label",
    "read_lidar",
    "read_pfm",
    "read_rgb",
    "read_split",
    "read_visibility",
    "save_camera",
    "trajectory_of",
    "write_depth",
    "write_label",
    "write_lidar",
    "write_pfm",
    "write_rgb",
    "write_split",
    "write_visibility",
]
