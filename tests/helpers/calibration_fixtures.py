"""Real published calibrations, written by the tests in the formats their tools write.

Calibration parameters only (no images): their values come from the sources named next to them. Two are synthetic
(``OCAM_LONG_INVPOL``, issue #35's kind of OCamCalib file, and ``OCAM_NEGATIVE_AXIS``, the kind whose world2cam
cancels on the optical axis), and say how they were made.
"""

from __future__ import annotations

import json
from pathlib import Path

from airfisheye_bench.studies.miniature_datasets.kitti360 import KITTI360  # its source is named there

# TUM-VI 512 cam0 / cam1 Double Sphere and EUCM: github:VladyslavUsenko/basalt data/tumvi_512_ds_calib.json and
# data/tumvi_512_eucm_calib.json (T_imu_cam, intrinsics, resolution; the IMU and vignette entries left out).
TUMVI_T_IMU_CAM = [
    {
        "px": 0.04548094812071685,
        "py": -0.07145370002838907,
        "pz": -0.046315428444919249,
        "qx": -0.013392900690257393,
        "qy": -0.6945866755293793,
        "qz": 0.7192437840259219,
        "qw": 0.007639340823570553,
    },
    {
        "px": -0.05546984222234079,
        "py": -0.06999334244486549,
        "pz": -0.049092582974927929,
        "qx": -0.01340980138125811,
        "qy": -0.7115668842588793,
        "qz": 0.7024477338114514,
        "qw": 0.007741299385907546,
    },
]
TUMVI_DS = [
    {
        "fx": 158.28600034966977,
        "fy": 158.2743455478755,
        "cx": 254.96116578191653,
        "cy": 256.8894394501779,
        "xi": -0.17213086034353243,
        "alpha": 0.5931177593944744,
    },
    {
        "fx": 157.91830144176309,
        "fy": 157.8901286125632,
        "cx": 252.56547609702953,
        "cy": 255.02489416194656,
        "xi": -0.17114780716007858,
        "alpha": 0.5925543396658507,
    },
]
TUMVI_EUCM = [
    {
        "fx": 191.14799836282189,
        "fy": 191.13150963902818,
        "cx": 254.9585771534443,
        "cy": 256.88154645599448,
        "alpha": 0.6291060881178562,
        "beta": 1.0418067381860868,
    },
    {
        "fx": 190.47905769226575,
        "fy": 190.44567561523216,
        "cx": 252.55882115024333,
        "cy": 255.02104780344699,
        "alpha": 0.6281040684983363,
        "beta": 1.041250259119081,
    },
]
# TUM-VI 512 pinhole-equi (Kalibr) cam0 / cam1: the TUM-VI dataset's published calibration (cvg.cit.tum.de), as
# quoted in public code that uses the dataset (e.g. an Undistort.m attached to a Kalibr issue, "pinhole-equi-512").
TUMVI_EQUI = [
    {
        "intrinsics": [190.97847715128717, 190.9733070521226, 254.93170605935475, 256.8974428996504],
        "distortion_coeffs": [
            0.0034823894022493434,
            0.0007150348452162257,
            -0.0020532361418706202,
            0.00020293673591811182,
        ],
    },
    {
        "intrinsics": [190.44236969414825, 190.4344384721956, 252.59949716835982, 254.91723064636983],
        "distortion_coeffs": [
            0.0034003170790442797,
            0.001766278153469831,
            -0.00266312569781606,
            0.0003299517423931039,
        ],
    },
]

# WoodScape front camera: github:valeoai/WoodScape scripts/calibration/front.json (commit 2bf2161).
WOODSCAPE_FRONT = {
    "extrinsic": {
        "quaternion": [0.5941767906169857, -0.5878843193897473, 0.3873184109007999, -0.3890121040340926],
        "translation": [3.7484, 0.0, 0.6601699999999999],
    },
    "intrinsic": {
        "aspect_ratio": 1.0,
        "cx_offset": 3.942,
        "cy_offset": -3.093,
        "height": 966.0,
        "k1": 339.749,
        "k2": -31.988,
        "k3": 48.275,
        "k4": -7.201,
        "model": "radial_poly",
        "poly_order": 4,
        "width": 1280.0,
    },
    "name": "FV",
}

# An OCamCalib v3.0 calibration of a Kodak PIXPRO SP360 4K (1440 x 1440): github:uts-magic-lab/kodak_pixpro_sp360_ros
# calib_results_kodak.txt, as the toolbox's export_data.m writes it.
OCAM_KODAK = """#polynomial coefficients for the DIRECT mapping function (ocam_model.ss in MATLAB). These are used by cam2world

5 -2.716972e+02 0.000000e+00 -2.741744e-06 1.840940e-06 -8.024838e-10 

#polynomial coefficients for the inverse mapping function (ocam_model.invpol in MATLAB). These are used by world2cam

13 583.439624 470.805865 97.165132 120.712689 100.686168 55.067847 67.348203 15.186683 1.492255 84.459767 105.607698 48.090642 7.785426 

#center: "row" and "column", starting from 0 (C convention)

728.648728 729.090632

#affine parameters "c", "d", "e"

1.001407 -0.000818 0.000221

#image size: "height" and "width"

1440 1440
"""  # noqa: W291 (the toolbox ends value lines with a space)

# The same camera calibrated with ROS cameracalibrator.py (plumb_bob): github:uts-magic-lab/kodak_pixpro_sp360_ros
# kodak.yaml, in camera_calibration_parsers' layout.
ROS_KODAK = """image_width: 1440
image_height: 1440
camera_name: kodak
camera_matrix:
  rows: 3
  cols: 3
  data: [559.7772332675477, 0, 654.6891822497959, 0, 537.9001480261843, 757.5374958985061, 0, 0, 1]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [-0.1710342568253523, 0.01562344385534763, -0.006842079559350427, 0.005880933792022186, 0]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]
projection_matrix:
  rows: 3
  cols: 4
  data: [471.8281555175781, 0, 686.7856496391687, 0, 0, 427.0946044921875, 763.6798197288299, 0, 0, 0, 1, 0]
"""

# Not a published calibration: a synthetic OCamCalib file like the one of issue #35 (1024 x 768, a 33-term
# world2cam). A lens r = 298.5 theta px; ss fitted to it (degree 4, a1 = 0); invpol made as OCamCalib's findinvpoly2
# makes it, with N = 32 (theta from -pi/2 in steps of 0.01 while ss has a root below the half diagonal, 640 px;
# MATLAB's polyfit, an unscaled QR); written as export_data.m writes it (%e for ss, %f for invpol). The fit's data
# reach 123 deg, as do the image's corners; beyond, the polynomial blows up (3.7e7 px at 180 deg), and rounded to six
# decimals it is -0.67 px on the axis.
OCAM_LONG_INVPOL = """#polynomial coefficients for the DIRECT mapping function (ocam_model.ss in MATLAB). These are used by cam2world

5 -3.029898e+02 0.000000e+00 1.860893e-03 -3.584921e-06 5.362977e-09 

#polynomial coefficients for the inverse mapping function (ocam_model.invpol in MATLAB). These are used by world2cam

33 471.506046 292.398142 -27.765258 18.727158 47.914054 -15.978052 -6.884066 32.972566 -17.426236 -12.862056 33.902565 -14.651267 -20.030652 14.978478 -28.507797 88.310964 170.792086 -331.018998 -593.163607 430.447262 1303.034394 225.634937 -1426.210411 -1288.543218 202.841411 1038.199331 706.318445 115.977403 -118.675726 -90.793563 -29.719208 -5.011245 -0.356129 

#center: "row" and "column", starting from 0 (C convention)

383.600000 511.300000

#affine parameters "c", "d", "e"

1.000400 0.000300 -0.000200

#image size: "height" and "width"

768 1024
"""  # noqa: W291 (as the toolbox writes it)

# Not a published calibration: a synthetic OCamCalib file of the kind that served a hole at the image's centre
# (1024 x 768; world2cam -0.64 px on the optical axis). The lens r = 152 theta + 60.8 theta^3 px; invpol is that lens
# 0.6 px short, plus 1e-3 px of a degree-24 Chebyshev polynomial of the fit's range (theta in [0, 1.9] rad; numpy's
# Chebyshev.basis(24, domain=[-pi/2, 1.9 - pi/2]).convert(kind=Polynomial)), the kind of component a least-squares fit
# of many terms leaves barely determined: in powers of theta - pi/2 its terms reach 3e11 px on the axis and cancel to
# -0.64 px, so float64 evaluates it there only to ~1e-4 px. Written with %f, as export_data.m writes invpol. ss:
# cam2world of the same lens (z = -rho / tan(theta)), degree 4 with a1 = 0, least squares over theta in [0, 1.9]
# (it and invpol disagree by up to 0.32 deg, most near the axis).
OCAM_NEGATIVE_AXIS = """#polynomial coefficients for the DIRECT mapping function (ocam_model.ss in MATLAB). These are used by cam2world

5 -1.539316e+02 0.000000e+00 5.806348e-05 1.902656e-06 -1.236907e-09 

#polynomial coefficients for the inverse mapping function (ocam_model.invpol in MATLAB). These are used by world2cam

25 473.808559 602.086754 286.636441 54.870485 -20.253571 291.037695 1255.200905 -5015.630553 -33190.998866 4583.557493 374497.611727 736672.245528 -1063880.120767 -6414705.969097 -8868222.889530 4878368.958006 37768344.534072 70507061.883607 78802388.651286 59847803.377973 31859974.052548 11787054.421998 2900272.291654 428039.406902 28729.189458 

#center: "row" and "column", starting from 0 (C convention)

383.600000 511.300000

#affine parameters "c", "d", "e"

1.000400 0.000300 -0.000200

#image size: "height" and "width"

768 1024
"""  # noqa: W291 (as the toolbox writes it)


def write_basalt(path: Path, intrinsics: list[dict], camera_type: str) -> Path:
    """basalt's calibration JSON (cereal layout) of TUM-VI's two cameras."""
    doc = {
        "value0": {
            "T_imu_cam": TUMVI_T_IMU_CAM,
            "intrinsics": [{"camera_type": camera_type, "intrinsics": p} for p in intrinsics],
            "resolution": [[512, 512], [512, 512]],
            "imu_update_rate": 200.0,
        }
    }
    path.write_text(json.dumps(doc, indent=4))
    return path


def write_kalibr_camchain(path: Path, model: str = "ds", cameras: int = 2) -> Path:
    """A Kalibr camchain.yaml of TUM-VI's 512 cameras (``cameras``: 2, or 1 for cam0 alone): ``ds`` (Double
    Sphere, basalt's values in Kalibr's intrinsics order xi, alpha, fu, fv, pu, pv) or ``pinhole-equi``."""
    blocks = []
    for i in range(cameras):
        if model == "ds":
            p = TUMVI_DS[i]
            intrinsics = [p["xi"], p["alpha"], p["fx"], p["fy"], p["cx"], p["cy"]]
            camera_model, distortion, coeffs = "ds", "none", []
        else:
            intrinsics = TUMVI_EQUI[i]["intrinsics"]
            camera_model, distortion, coeffs = "pinhole", "equidistant", TUMVI_EQUI[i]["distortion_coeffs"]
        block = [
            f"cam{i}:",
            f"  cam_overlaps: [{1 - i}]",
            f"  camera_model: {camera_model}",
            f"  distortion_coeffs: [{', '.join(repr(c) for c in coeffs)}]",
            f"  distortion_model: {distortion}",
            f"  intrinsics: [{', '.join(repr(v) for v in intrinsics)}]",
            "  resolution: [512, 512]",
            f"  rostopic: /cam{i}/image_raw",
        ]
        if i == 1:  # an illustrative baseline (not TUM-VI's): 10.1 cm along x
            block += [
                "  T_cn_cnm1:",
                "  - [1.0, 0.0, 0.0, -0.101]",
                "  - [0.0, 1.0, 0.0, 0.0]",
                "  - [0.0, 0.0, 1.0, 0.0]",
                "  - [0.0, 0.0, 0.0, 1.0]",
            ]
        blocks.append("\n".join(block))
    path.write_text("\n".join(blocks) + "\n")
    return path


def write_kitti360(path: Path, name: str = "image_02") -> Path:
    """KITTI-360 ``calibration/image_0x.yaml`` in its OpenCV FileStorage layout (``%YAML:1.0``)."""
    p = KITTI360[name]
    path.write_text(
        "%YAML:1.0\n---\nmodel_type: MEI\n"
        f"camera_name: {name}\nimage_width: 1400\nimage_height: 1400\n"
        f"mirror_parameters:\n   xi: {p['xi']:.16e}\n"
        "distortion_parameters:\n"
        + "".join(f"   {k}: {p[k]:.16e}\n" for k in ("k1", "k2", "p1", "p2"))
        + "projection_parameters:\n"
        + "".join(f"   {k}: {p[k]:.16e}\n" for k in ("gamma1", "gamma2", "u0", "v0"))
    )
    return path


def write_camodocal_kannala_brandt(path: Path, name: str = "cam0") -> Path:
    """TUM-VI 512 cam0's pinhole-equi calibration (``TUMVI_EQUI[0]``) as camodocal's ``KANNALA_BRANDT`` YAML, laid
    out as ``EquidistantCamera::Parameters::writeToYamlFile`` writes it (github:hengli/camodocal): Kalibr's k1..k4
    are camodocal's k2..k5, fu, fv, pu, pv its mu, mv, u0, v0."""
    (fu, fv, pu, pv), k = TUMVI_EQUI[0]["intrinsics"], TUMVI_EQUI[0]["distortion_coeffs"]
    values = {"k2": k[0], "k3": k[1], "k4": k[2], "k5": k[3], "mu": fu, "mv": fv, "u0": pu, "v0": pv}
    path.write_text(
        f"%YAML:1.0\n---\nmodel_type: KANNALA_BRANDT\ncamera_name: {name}\nimage_width: 512\nimage_height: 512\n"
        "projection_parameters:\n" + "".join(f"   {key}: {v:.16e}\n" for key, v in values.items())
    )
    return path
