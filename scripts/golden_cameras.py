"""Write the camera models' golden values (``tests/geometry/golden/*.json``) from the implementations people trust.

Each output file names its reference, the version or commit used and this command. The calibrations are the
published ones of ``tests/geometry/golden/calibrations.json``; the sample points cover each model's valid field of
view (incidence angles from 0 to just inside the region's edge, all azimuths, ranges 0.5-50 m) and the pixels
cover the image. Nothing here uses this project's camera code to make a reference value: the references are

- ``basalt.json``: basalt's camera headers compiled as they are (``scripts/golden/basalt_cameras.cpp``, built with
  g++ against basalt-headers, Sophus and Debian's libeigen3-dev): Double Sphere, EUCM, KB4 (beyond 90 deg) and the
  unified model without distortion (basalt's ``alpha = xi / (1 + xi)``, ``f_basalt = f / (1 + xi)``).
- ``opencv_fisheye.json``: ``cv2.fisheye.projectPoints`` / ``undistortPoints`` (valid below 90 deg only).
- ``opencv_omnidir.json``: ``cv2.omnidir.projectPoints`` (opencv-contrib), the full MEI model with p1, p2.
- ``opencv_pinhole.json``: ``cv2.projectPoints`` and ``cv2.undistortPoints`` with tight criteria (plumb_bob), and
  with no distortion on the ideal pinhole (its focal ``(W / 2) / tan(fov_deg / 2)`` written out here).
- ``kitti360.json``: the KITTI-360 devkit's ``CameraFisheye.cam2image`` (ignores p1, p2: compared with them zeroed).
- ``woodscape.json``: WoodScape's ``projection.py`` (``Camera`` + ``RadialPolyCamProjection``), both directions.
- ``ocamcalib.json``: OCamCalib's ``world2cam`` / ``cam2world`` (the toolbox's C functions, transcribed below
  line by line: the toolbox is MATLAB with a C export and has no package to install), on the Kodak SP360's
  calibration and on ``OCAM_NEGATIVE_AXIS`` of ``tests/helpers/calibration_fixtures.py`` (a synthetic file whose world2cam
  is negative on the axis; read as the toolbox's ``get_ocam_model`` reads it), there with pixels near the centre.

Usage (each reference is optional; the files of the missing ones are left as they are)::

    python scripts/golden_cameras.py --basalt-headers DIR --sophus DIR --kitti360 DIR --woodscape DIR

with ``cv2`` (opencv-contrib-python-headless) importable for the OpenCV files.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
GOLDEN = ROOT / "tests" / "geometry" / "golden"
CALIBRATIONS = json.loads((GOLDEN / "calibrations.json").read_text())["cameras"]
COMMAND = "python scripts/golden_cameras.py " + " ".join(sys.argv[1:])


def directions(theta_max_deg: float, n_theta: int = 24, n_phi: int = 16, seed: int = 0) -> np.ndarray:
    """Points ``[N, 3]`` with incidence angles in ``[0, theta_max]``, all azimuths, ranges 0.5-50 m."""
    rng = np.random.default_rng(seed)
    theta = np.radians(
        np.concatenate([np.linspace(0.0, theta_max_deg, n_theta), rng.uniform(0, theta_max_deg, 64)])
    )
    phi = np.linspace(0.0, 2 * np.pi, n_phi, endpoint=False)
    t, p = (a.ravel() for a in np.meshgrid(theta[:n_theta], phi))
    t = np.concatenate([t, theta[n_theta:]])
    p = np.concatenate([p, rng.uniform(0, 2 * np.pi, len(theta) - n_theta)])
    dirs = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1)
    return dirs * rng.uniform(0.5, 50.0, (len(dirs), 1))


def pixels(width: int, height: int, n: int = 400, seed: int = 1) -> np.ndarray:
    """Pixel positions ``[N, 2]`` over the whole image (a grid plus random ones)."""
    rng = np.random.default_rng(seed)
    u, v = np.meshgrid(np.linspace(0, width - 1, 15), np.linspace(0, height - 1, 15))
    grid = np.stack([u.ravel(), v.ravel()], -1)
    return np.concatenate([grid, rng.uniform([0, 0], [width - 1, height - 1], (n - len(grid), 2))])


def write(name: str, source: str, version: str, cases: list[dict]) -> None:
    out = {"source": source, "version": version, "command": COMMAND, "cases": cases}
    path = GOLDEN / name
    path.write_text(json.dumps(out) + "\n")
    print(f"wrote {path.relative_to(ROOT)} ({len(cases)} cases)")


def git_head(path: Path) -> str:
    try:
        return subprocess.run(
            ["git", "-C", str(path), "rev-parse", "HEAD"], capture_output=True, text=True, check=True
        ).stdout.strip()
    except (subprocess.CalledProcessError, FileNotFoundError):
        return "(not a git checkout)"


# ---------------------------------------------------------------------------------------------- basalt
def run_basalt(binary: Path, model: str, params: list[float], points: np.ndarray, uv: np.ndarray):
    lines = [f"{model} {len(params)} " + " ".join(repr(float(p)) for p in params), str(len(points))]
    lines += [" ".join(repr(float(c)) for c in p) for p in points]
    lines += [str(len(uv))] + [" ".join(repr(float(c)) for c in q) for q in uv]
    out = subprocess.run(
        [str(binary)], input="\n".join(lines) + "\n", capture_output=True, text=True, check=True
    )
    rows = [list(map(float, line.split())) for line in out.stdout.splitlines()]
    proj, unproj = np.array(rows[: len(points)]), np.array(rows[len(points) :])
    return proj[:, 1:], proj[:, 0] > 0, unproj[:, 1:], unproj[:, 0] > 0


def basalt_cases(headers: Path, sophus: Path) -> tuple[list[dict], str]:
    build = Path(tempfile.mkdtemp())
    binary = build / "basalt_cameras"
    subprocess.run(
        [
            "g++",
            "-O1",
            "-std=c++17",
            "-I",
            str(headers / "include"),
            "-I",
            str(sophus),
            "-I",
            "/usr/include/eigen3",
            "-DSOPHUS_USE_BASIC_LOGGING",
            str(ROOT / "scripts" / "golden" / "basalt_cameras.cpp"),
            "-o",
            str(binary),
        ],
        check=True,
    )
    cases = []
    specs = [
        (
            "tumvi512_cam0_ds",
            "ds",
            lambda c: [c["fx"], c["fy"], c["cx"], c["cy"], c["xi"], c["alpha"]],
            118.0,
        ),
        (
            "tumvi512_cam0_eucm",
            "eucm",
            lambda c: [c["fx"], c["fy"], c["cx"], c["cy"], c["alpha"], c["beta"]],
            118.0,
        ),
        (
            "tumvi512_cam0_kb",
            "kb4",
            lambda c: [c[k] for k in ("fx", "fy", "cx", "cy", "k1", "k2", "k3", "k4")],
            115.0,
        ),
    ]
    for name in ("kitti360_image_02", "kitti360_image_03"):
        # basalt's unified model: alpha = xi / (1 + xi), focal lengths divided by (1 + xi); no distortion.
        specs.append(
            (
                name,
                "unified",
                lambda c: [
                    c["fx"] / (1 + c["xi"]),
                    c["fy"] / (1 + c["xi"]),
                    c["cx"],
                    c["cy"],
                    c["xi"] / (1 + c["xi"]),
                ],
                None,
            )
        )
    for name, bmodel, to_params, theta_max in specs:
        cam = dict(CALIBRATIONS[name]["camera"])
        if bmodel == "unified":
            cam.update(k1=0.0, k2=0.0, p1=0.0, p2=0.0)
            theta_max = math.degrees(math.acos(-1.0 / cam["xi"])) - 0.05  # basalt's region edge: z > -d / xi
        points = directions(theta_max)
        uv_in = pixels(cam["width"], cam["height"])
        uv, valid, rays, ray_ok = run_basalt(binary, bmodel, to_params(cam), points, uv_in)
        keep = ray_ok & np.isfinite(rays).all(1)
        cases.append(
            {
                "name": f"{name} ({bmodel})" + (" without distortion" if bmodel == "unified" else ""),
                "calibration": name,
                "camera": cam,
                "project": {"points": points.tolist(), "uv": uv.tolist(), "valid": valid.tolist()},
                "unproject": {
                    "uv": uv_in[keep].tolist(),
                    "rays": (rays[keep] / np.linalg.norm(rays[keep], axis=1, keepdims=True)).tolist(),
                },
            }
        )
    shutil.rmtree(build, ignore_errors=True)
    return cases, f"basalt-headers @ {git_head(headers)}, Sophus @ {git_head(sophus)}, Eigen 3.4.0 (Debian)"


# ---------------------------------------------------------------------------------------------- OpenCV
def opencv_fisheye_cases(cv2) -> list[dict]:
    cases = []
    for skew in (0.0, 0.002):
        cam = dict(CALIBRATIONS["tumvi512_cam0_kb"]["camera"], skew=skew)
        K = np.array([[cam["fx"], cam["fx"] * skew, cam["cx"]], [0, cam["fy"], cam["cy"]], [0, 0, 1.0]])
        D = np.array([cam["k1"], cam["k2"], cam["k3"], cam["k4"]])
        points = directions(89.5)  # cv2.fisheye uses theta = atan(r / z): valid below 90 deg only
        uv, _ = cv2.fisheye.projectPoints(points[:, None, :], np.zeros(3), np.zeros(3), K, D, alpha=skew)
        uv = uv[:, 0, :]
        # Unproject: pixels whose ray is below 90 deg (undistortPoints clamps theta_d at pi/2), as normalised
        # (x/z, y/z) with tight criteria.
        crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-15)
        uv_in = uv[np.linalg.norm(points[:, :2], axis=1) / points[:, 2] < 20]  # within ~87 deg
        und = cv2.fisheye.undistortPoints(uv_in[:, None, :], K, D, criteria=crit)[:, 0, :]
        rays = np.concatenate([und, np.ones((len(und), 1))], 1)
        case = {
            "name": f"tumvi512_cam0_kb, skew (alpha) {skew}" + (" (a skew added to test it)" if skew else ""),
            "calibration": "tumvi512_cam0_kb",
            "camera": cam,
            "project": {"points": points.tolist(), "uv": uv.tolist(), "valid": [True] * len(points)},
        }
        if not skew:  # cv2.fisheye.undistortPoints reads fx, fy, cx, cy from K and ignores its skew entry
            rays /= np.linalg.norm(rays, axis=1, keepdims=True)
            case["unproject"] = {"uv": uv_in.tolist(), "rays": rays.tolist()}
        cases.append(case)
    return cases


def opencv_omnidir_cases(cv2) -> list[dict]:
    cases = []
    for name in ("kitti360_image_02", "kitti360_image_03"):
        cam = CALIBRATIONS[name]["camera"]
        K = np.array([[cam["fx"], 0.0, cam["cx"]], [0, cam["fy"], cam["cy"]], [0, 0, 1.0]])
        D = np.array([[cam["k1"], cam["k2"], cam["p1"], cam["p2"]]])
        points = directions(math.degrees(math.acos(-1.0 / cam["xi"])) - 0.05)
        uv, _ = cv2.omnidir.projectPoints(
            points[:, None, :], np.zeros((1, 3)), np.zeros((1, 3)), K, float(cam["xi"]), D
        )
        cases.append(
            {
                "name": f"{name} (MEI with k1, k2, p1, p2)",
                "calibration": name,
                "camera": cam,
                "project": {
                    "points": points.tolist(),
                    "uv": uv[:, 0, :].tolist(),
                    "valid": [True] * len(points),
                },
            }
        )
    return cases


def opencv_pinhole_cases(cv2) -> list[dict]:
    cam = CALIBRATIONS["ros_kodak_plumb_bob"]["camera"]
    K = np.array([[cam["fx"], 0.0, cam["cx"]], [0, cam["fy"], cam["cy"]], [0, 0, 1.0]])
    D = np.array([cam["k1"], cam["k2"], cam["p1"], cam["p2"], cam["k3"]])
    points = directions(55.0)  # beyond ~60 deg this calibration's distortion flattens out (ill-conditioned)
    uv, _ = cv2.projectPoints(points[:, None, :], np.zeros(3), np.zeros(3), K, D)
    uv = uv[:, 0, :]
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-15)
    und = cv2.undistortPoints(uv[:, None, :], K, D, None, None, None, crit)[:, 0, :]
    rays = np.concatenate([und, np.ones((len(und), 1))], 1)
    return [
        {
            "name": "ros_kodak_plumb_bob",
            "calibration": "ros_kodak_plumb_bob",
            "camera": cam,
            "project": {"points": points.tolist(), "uv": uv.tolist(), "valid": [True] * len(points)},
            "unproject": {
                "uv": uv.tolist(),
                "rays": (rays / np.linalg.norm(rays, axis=1, keepdims=True)).tolist(),
            },
        },
        ideal_pinhole_case(cv2),
    ]


#: The ideal pinhole (``model: pinhole``): a 100 deg field of view across a 4:3 frame, the principal point off-centre.
IDEAL_PINHOLE = {"model": "pinhole", "width": 640, "height": 480, "fov_deg": 100.0, "cx": 322.7, "cy": 236.4}


def ideal_pinhole_case(cv2) -> dict:
    """``cv2.projectPoints`` / ``cv2.undistortPoints`` with zero distortion, ``fx = fy = (W / 2) / tan(fov / 2)``."""
    cam = IDEAL_PINHOLE
    f = (cam["width"] / 2.0) / math.tan(math.radians(cam["fov_deg"]) / 2.0)
    K = np.array([[f, 0.0, cam["cx"]], [0, f, cam["cy"]], [0, 0, 1.0]])
    D = np.zeros(5)
    points = directions(80.0, seed=3)  # the frame's corners are at 60 deg; beyond, pixels a larger sensor has
    uv, _ = cv2.projectPoints(points[:, None, :], np.zeros(3), np.zeros(3), K, D)
    uv = uv[:, 0, :]
    pix = pixels(cam["width"], cam["height"], seed=4)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-15)
    und = cv2.undistortPoints(pix[:, None, :], K, D, None, None, None, crit)[:, 0, :]
    rays = np.concatenate([und, np.ones((len(und), 1))], 1)
    return {
        "name": "ideal_pinhole",
        "camera": cam,
        "project": {"points": points.tolist(), "uv": uv.tolist(), "valid": [True] * len(points)},
        "unproject": {
            "uv": pix.tolist(),
            "rays": (rays / np.linalg.norm(rays, axis=1, keepdims=True)).tolist(),
        },
    }


# ---------------------------------------------------------------------------------------------- KITTI-360
def kitti360_cases(devkit: Path) -> list[dict]:
    sys.path.insert(0, str(devkit))
    from kitti360scripts.helpers.project import CameraFisheye  # the devkit's own code

    cases = []
    for name in ("kitti360_image_02", "kitti360_image_03"):
        cam = CALIBRATIONS[name]["camera"]
        fisheye = object.__new__(CameraFisheye)  # no dataset on disk: set the intrinsics its yaml would give
        fisheye.fi = {
            "mirror_parameters": {"xi": cam["xi"]},
            "distortion_parameters": {"k1": cam["k1"], "k2": cam["k2"], "p1": cam["p1"], "p2": cam["p2"]},
            "projection_parameters": {
                "gamma1": cam["fx"],
                "gamma2": cam["fy"],
                "u0": cam["cx"],
                "v0": cam["cy"],
            },
        }
        points = directions(math.degrees(math.acos(-1.0 / cam["xi"])) - 0.05)
        u, v, _ = fisheye.cam2image(points.T.copy())
        cases.append(
            {
                "name": f"{name}, devkit cam2image (p1 = p2 = 0: the devkit ignores them)",
                "calibration": name,
                "camera": dict(cam, p1=0.0, p2=0.0),
                "project": {
                    "points": points.tolist(),
                    "uv": np.stack([u, v], -1).tolist(),
                    "valid": [True] * len(points),
                },
            }
        )
    return cases


# ---------------------------------------------------------------------------------------------- WoodScape
def woodscape_cases(repo: Path) -> list[dict]:
    sys.path.insert(0, str(repo / "scripts" / "calibration"))
    import projection  # WoodScape's scripts/calibration/projection.py

    config = json.loads((repo / "scripts" / "calibration" / "front.json").read_text())["intrinsic"]
    lens = projection.RadialPolyCamProjection([config[k] for k in ("k1", "k2", "k3", "k4")])
    camera = projection.Camera(
        lens=lens,
        translation=np.zeros(3),
        rotation=np.eye(3),
        size=(int(config["width"]), int(config["height"])),
        principle_point=(config["cx_offset"], config["cy_offset"]),
        aspect_ratio=config["aspect_ratio"],
    )
    cam = CALIBRATIONS["woodscape_front"]["camera"]
    assert abs(camera.cx - cam["cx"]) < 1e-12 and abs(camera.cy - cam["cy"]) < 1e-12, (camera.cx, camera.cy)
    points = directions(112.0)
    points = points[np.hypot(points[:, 0], points[:, 1]) > 0]  # on the axis projection.py divides into junk
    uv = camera.project_3d_to_2d(points)
    uv_in = pixels(cam["width"], cam["height"])
    rays = camera.project_2d_to_3d(uv_in, norm=np.ones(len(uv_in)))
    return [
        {
            "name": "woodscape_front",
            "calibration": "woodscape_front",
            "camera": cam,
            "project": {"points": points.tolist(), "uv": uv.tolist(), "valid": [True] * len(points)},
            "unproject": {"uv": uv_in.tolist(), "rays": rays.tolist()},
        }
    ]


# ---------------------------------------------------------------------------------------------- OCamCalib
def ocam_world2cam(point3d, invpol, xc, yc, c, d, e):
    """OCamCalib ``world2cam`` (ocam_functions.c), line by line: ``point3d`` in OCamCalib's frame, returns
    ``(row, column)``."""
    norm = math.sqrt(point3d[0] * point3d[0] + point3d[1] * point3d[1])
    theta = math.atan(point3d[2] / norm) if norm != 0 else 0.0
    if norm != 0:
        invnorm = 1 / norm
        t = theta
        rho = invpol[0]
        t_i = 1.0
        for i in range(1, len(invpol)):
            t_i *= t
            rho += t_i * invpol[i]
        x = point3d[0] * invnorm * rho
        y = point3d[1] * invnorm * rho
        return x * c + y * d + xc, x * e + y + yc
    return xc, yc


def ocam_cam2world(point2d, pol, xc, yc, c, d, e):
    """OCamCalib ``cam2world`` (ocam_functions.c), line by line: ``(row, column)`` -> unit vector, OCamCalib frame."""
    invdet = 1 / (c - d * e)
    xp = invdet * ((point2d[0] - xc) - d * (point2d[1] - yc))
    yp = invdet * (-e * (point2d[0] - xc) + c * (point2d[1] - yc))
    r = math.sqrt(xp * xp + yp * yp)
    zp = pol[0]
    r_i = 1.0
    for i in range(1, len(pol)):
        r_i *= r
        zp += r_i * pol[i]
    invnorm = 1 / math.sqrt(xp * xp + yp * yp + zp * zp)
    return invnorm * xp, invnorm * yp, invnorm * zp


def ocam_model(text: str) -> dict:
    """A ``calib_results.txt`` as OCamCalib's ``get_ocam_model`` (ocam_functions.c) reads it: each of the five
    ``#`` headers skipped, then its numbers in order (ss: its length and coefficients; invpol: the same; the centre
    row, column; c, d, e; height, width), as this project's camera dict."""
    numbers = [float(tok) for line in text.splitlines() if not line.startswith("#") for tok in line.split()]
    n_ss = int(numbers[0])
    ss, rest = numbers[1 : 1 + n_ss], numbers[1 + n_ss :]
    n_inv = int(rest[0])
    invpol, (xc, yc, c, d, e, height, width) = rest[1 : 1 + n_inv], rest[1 + n_inv :]
    return {
        "model": "ocam", "width": int(width), "height": int(height), "cx": yc, "cy": xc, "c": c, "d": d, "e": e,
        "cam2world": ss, "world2cam": invpol,
    }  # fmt: skip


def near_centre(cam: dict, radii: list[float], azimuths: int = 8) -> np.ndarray:
    """Pixel positions ``[N, 2]`` on circles of ``radii`` about OCam's centre, and the centre itself."""
    a = np.linspace(0.0, 2 * np.pi, azimuths, endpoint=False)
    r = np.asarray(radii)[:, None]
    ring = np.stack([cam["cx"] + r * np.cos(a), cam["cy"] + r * np.sin(a)], -1).reshape(-1, 2)
    return np.concatenate([[[cam["cx"], cam["cy"]]], ring])


def ocam_case(name: str, calibration: str, cam: dict, points: np.ndarray, uv_in: np.ndarray) -> dict:
    xc, yc = cam["cy"], cam["cx"]  # OCamCalib's centre is (row, column)
    args = (xc, yc, cam["c"], cam["d"], cam["e"])
    uv = []
    for x, y, z in points:  # this project's frame (x right, y down, z forward) -> OCamCalib's (row, col, -z)
        row, col = ocam_world2cam((y, x, -z), cam["world2cam"], *args)
        uv.append((col, row))
    rays = []
    for u, v in uv_in:
        xo, yo, zo = ocam_cam2world((v, u), cam["cam2world"], *args)
        rays.append((yo, xo, -zo))
    return {
        "name": name,
        "calibration": calibration,
        "camera": cam,
        "project": {"points": points.tolist(), "uv": uv, "valid": [True] * len(points)},
        "cam2world": {"uv": uv_in.tolist(), "rays": rays},
    }


def ocam_cases() -> list[dict]:
    kodak = CALIBRATIONS["ocam_kodak_sp360"]["camera"]
    kodak_case = ocam_case(
        "ocam_kodak_sp360",
        "ocam_kodak_sp360",
        kodak,
        directions(128.0),
        pixels(kodak["width"], kodak["height"]),
    )
    sys.path.insert(0, str(ROOT))
    from tests.helpers.calibration_fixtures import (
        OCAM_NEGATIVE_AXIS,  # the tests' synthetic file (no camera code)
    )

    cam = ocam_model(OCAM_NEGATIVE_AXIS)
    # world2cam is compared on the axis itself and from 30 deg out: nearer, its terms cancel from 3e11 px and float64
    # has its radius only to ~1e-4 px (the toolbox's sum of powers and Horner's rule, each in its own way).
    points = directions(120.0)
    theta = np.degrees(np.arctan2(np.hypot(points[:, 0], points[:, 1]), points[:, 2]))
    points = np.concatenate([[[0.0, 0.0, 2.0]], points[theta >= 30.0]])
    # cam2world on circles about the centre, 0.1-60 px (incidence 0-22 deg), where the inverse of world2cam had no
    # ray, and over the image.
    radii = [0.1, 0.3, 0.7, 1.0, 1.5, 2.0, 3.0, 5.0, 8.0, 13.0, 20.0, 30.0, 45.0, 60.0]
    uv_in = np.concatenate([near_centre(cam, radii), pixels(cam["width"], cam["height"])])
    negative_case = ocam_case("ocam_negative_axis", "OCAM_NEGATIVE_AXIS", cam, points, uv_in)
    return [kodak_case, negative_case]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--basalt-headers", type=Path, help="checkout of github:VladyslavUsenko/basalt-headers"
    )
    parser.add_argument("--sophus", type=Path, help="checkout of Sophus at the commit basalt-headers pins")
    parser.add_argument("--kitti360", type=Path, help="checkout of github:autonomousvision/kitti360Scripts")
    parser.add_argument("--woodscape", type=Path, help="checkout of github:valeoai/WoodScape")
    args = parser.parse_args()
    if args.basalt_headers and args.sophus:
        cases, version = basalt_cases(args.basalt_headers, args.sophus)
        write(
            "basalt.json",
            "basalt include/basalt/camera/{double_sphere_camera,extended_camera,"
            "kannala_brandt_camera4,unified_camera}.hpp, compiled (scripts/golden/basalt_cameras.cpp)",
            version,
            cases,
        )
    try:
        import cv2  # opencv-contrib-python-headless
    except ImportError:
        cv2 = None
        print("cv2 not importable: the OpenCV files are left as they are")
    if cv2 is not None:
        version = f"opencv-contrib-python-headless {cv2.__version__}"
        write(
            "opencv_fisheye.json",
            "cv2.fisheye.projectPoints / cv2.fisheye.undistortPoints",
            version,
            opencv_fisheye_cases(cv2),
        )
        write(
            "opencv_omnidir.json",
            "cv2.omnidir.projectPoints (opencv_contrib ccalib)",
            version,
            opencv_omnidir_cases(cv2),
        )
        write(
            "opencv_pinhole.json",
            "cv2.projectPoints / cv2.undistortPoints (criteria 200 iterations, eps 1e-15)",
            version,
            opencv_pinhole_cases(cv2),
        )
    if args.kitti360:
        write(
            "kitti360.json",
            "KITTI-360 devkit kitti360scripts/helpers/project.py CameraFisheye.cam2image",
            f"kitti360Scripts @ {git_head(args.kitti360)}",
            kitti360_cases(args.kitti360),
        )
    if args.woodscape:
        write(
            "woodscape.json",
            "WoodScape scripts/calibration/projection.py (Camera, RadialPolyCamProjection)",
            f"WoodScape @ {git_head(args.woodscape)}",
            woodscape_cases(args.woodscape),
        )
    write(
        "ocamcalib.json",
        "OCamCalib world2cam / cam2world (ocam_functions.c of the toolbox's C export), "
        "transcribed line by line in scripts/golden_cameras.py",
        "OCamCalib v3 C functions",
        ocam_cases(),
    )


if __name__ == "__main__":
    main()
