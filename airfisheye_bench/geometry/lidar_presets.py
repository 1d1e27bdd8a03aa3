"""Named spinning LiDARs: channel tables, azimuth offsets, beam origins and points per revolution, with sources.

Each preset is the keyword arguments of :class:`~airfisheye_bench.geometry.lidar.LidarSpec` (plain data, so that
this module imports nothing): ``LidarSpec.from_preset(name)`` builds it. Tables are in ring order (ring 0 = the
lowest beam); where a source lists lasers in firing / ID order, the table is sorted by elevation here and the
per-laser offsets follow their laser. Frame: x forward, y left, z up; an azimuth offset is counter-clockwise seen
from above; a beam origin is ``(radial, tangential, vertical)`` metres (along the beam's horizontal direction, to
its left, up).

============  ========  =====================  ==========================================================
preset        channels  points / revolution    source of the table
============  ========  =====================  ==========================================================
``paper``     64        2048 over 270 deg      the paper's sensor (64 channels, 270 deg, 120 m), uniform
``hdl64e``    64        2083                   KITTI's HDL-64E S2 factory calibration (per-laser values)
``hdl32e``    32        1084 (20 Hz)           HDL-32E manual: vertical angle per laser, -30.67 to +10.67 deg
``vlp16``     16        1800 (10 Hz, 0.2 deg)  VLP-16 manual: vertical angles and vertical corrections
``vlp32c``    32        1800 (10 Hz, 0.2 deg)  VLP-32C manual: vertical angles and azimuth offsets
``os1-64``    64        1024 (1024x10)         Ouster SDK design values (gen1 OS-1-64)
``os1-128``   128       1024 (1024x10)         OS1 rev 7 datasheet: 45 deg uniform (no per-beam table)
``pandar64``  64        1800 (10 Hz, 0.2 deg)  Hesai Pandar64 design elevations (HesaiLidar_General_SDK)
============  ========  =====================  ==========================================================

Example:
    >>> sorted(LIDAR_PRESETS)[:3]
    ['hdl32e', 'hdl64e', 'os1-128']
    >>> len(LIDAR_PRESETS["hdl64e"]["elevations_deg"]), LIDAR_PRESETS["hdl64e"]["hfov_deg"]
    (64, 360.0)
"""

from __future__ import annotations

from typing import Any

# ------------------------------------------------------------------------------------------------ HDL-64E
# KITTI's Velodyne HDL-64E S2 calibration, velodynecalib_S2_factory_flatness_intensity.xml (linked from
# cvlibs.net/datasets/kitti/raw_data.php), as transcribed in github:olafbooij/ittik src/calibration_kitti.hpp.
# Per laser ID 0-63 (0-31 the upper block, 32-63 the lower): rotCorrection (deg), vertCorrection (deg),
# vertOffsetCorrection (cm), horizOffsetCorrection (cm). Velodyne's manual (HDL-64E S2 appendix F) computes
# x = d cos(v) sin(a) - h cos(a), y = d cos(v) cos(a) + h sin(a), z = d sin(v) + vertOffset with a = encoder -
# rotCorrection in its frame (x right, y forward): in ours the laser's azimuth offset is +rotCorrection, its
# origin vertOffset above the base and h to the left of its beam.
_HDL64E_LASERS = (
    (-5.0704789, -7.287312, 19.737808, 2.5999999),
    (-2.9607918, -6.9990368, 19.774553, -2.5999999),
    (2.7121143, 0.180617, 20.679979, 2.5999999),
    (4.9628944, 0.57880998, 20.729954, -2.5999999),
    (-0.79710281, -6.675746, 19.81571, 2.5999999),
    (1.4592539, -6.3288889, 19.859804, -2.5999999),
    (-1.5792946, -8.7114143, 19.555548, 2.5999999),
    (0.68123782, -8.3104696, 19.606993, -2.5999999),
    (3.4655483, -5.958395, 19.906839, 2.5999999),
    (5.7106166, -5.6106009, 19.950935, -2.5999999),
    (2.708117, -8.0580254, 19.639328, 2.5999999),
    (4.9553113, -7.6787701, 19.687834, -2.5999999),
    (-5.0824332, -3.235882, 20.250784, 2.5999999),
    (-2.8410845, -2.8738379, 20.296349, -2.5999999),
    (-5.8479395, -5.2507782, 19.996502, 2.5999999),
    (-3.5962763, -4.9137921, 20.039125, -2.5999999),
    (-0.85072309, -2.546633, 20.337505, 2.5999999),
    (1.4546897, -2.207566, 20.380131, -2.5999999),
    (-1.5957572, -4.5881028, 20.080282, 2.5999999),
    (0.6645931, -4.2155242, 20.127317, -2.5999999),
    (3.4167359, -1.833245, 20.427166, 2.5999999),
    (5.6595216, -1.49388, 20.469791, -2.5999999),
    (2.6582236, -3.935853, 20.162594, 2.5999999),
    (4.9000001, -3.5393341, 20.212568, -2.5999999),
    (-5.0803046, 0.871566, 20.766701, 2.5999999),
    (-2.8516858, 1.304757, 20.821083, -2.5999999),
    (-5.8603926, -1.201239, 20.506536, 2.5999999),
    (-3.6049912, -0.80315, 20.556513, -2.5999999),
    (-0.87220359, 1.573966, 20.854891, 2.5999999),
    (1.4057015, 1.9367, 20.900455, -2.5999999),
    (-1.6291088, -0.45182899, 20.600607, 2.5999999),
    (0.62309581, -0.088762, 20.646173, -2.5999999),
    (-7.9968266, -22.856577, 10.795722, 2.5999999),
    (-4.5520601, -22.437605, 10.849071, -2.5999999),
    (4.354651, -11.598996, 12.139602, 2.5999999),
    (7.6049747, -10.956945, 12.212004, -2.5999999),
    (-1.1401243, -21.935509, 10.912581, 2.5999999),
    (2.4086945, -21.318125, 10.990064, -2.5999999),
    (-2.3721526, -24.999201, 10.517547, 2.5999999),
    (1.1519399, -24.506605, 10.582327, -2.5999999),
    (5.77879, -20.787691, 11.056115, 2.5999999),
    (9.1956568, -20.222572, 11.125976, -2.5999999),
    (4.5604758, -23.971016, 10.652189, 2.5999999),
    (8.1412535, -23.322384, 10.736023, -2.5999999),
    (-7.856997, -16.55401, 11.568009, 2.5999999),
    (-4.4215517, -16.176632, 11.612466, -2.5999999),
    (-9.1637096, -19.736372, 11.185676, 2.5999999),
    (-5.6806865, -19.320236, 11.236484, -2.5999999),
    (-1.1443137, -15.656734, 11.673436, 2.5999999),
    (2.2717576, -15.188733, 11.728055, -2.5999999),
    (-2.3783834, -18.797075, 11.299995, 2.5999999),
    (1.1092063, -18.323431, 11.357154, -2.5999999),
    (5.5492816, -14.598064, 11.796646, 2.5999999),
    (8.9375477, -14.048302, 11.860156, -2.5999999),
    (4.3666, -17.73037, 11.428286, 2.5999999),
    (7.8623509, -17.186821, 11.493066, -2.5999999),
    (-7.7044425, -10.470731, 12.266623, 2.5999999),
    (-4.3473101, -10.06249, 12.31235, -2.5999999),
    (-8.9924641, -13.484814, 11.924937, 2.5999999),
    (-5.560183, -13.040989, 11.975745, -2.5999999),
    (-1.0891469, -9.5735149, 12.366969, 2.5999999),
    (2.148736, -9.0260181, 12.427939, -2.5999999),
    (-2.3586042, -12.562096, 12.030364, 2.5999999),
    (1.0275339, -12.115005, 12.081173, -2.5999999),
)

# ------------------------------------------------------------------------------------------------ HDL-32E
#: Velodyne HDL-32E user's manual (63-9113), "Laser Firing Sequence": the vertical angle (deg) of each laser in firing
#: order, which is the order of the Ethernet packet (DSR # 0-31). The lowest laser fires first, then the lower and
#: upper banks of 16 interleave (against ghosting from retro-reflectors); DSR 15 is the 0 deg laser. The manual
#: prints -6.66 and -26.66 where the 4/3 deg grid and the ROS driver's 32db.yaml have -6.67 / -26.67. Appendix D:
#: the x and y offsets are zero and every laser fires from the centre of the lenses, where the driver's (and
#: nuScenes') frame has its origin; the vertical angle is the only per-laser parameter: no beam origins.
HDL32E_VERTICAL_ANGLES_DEG = (
    -30.67, -9.33, -29.33, -8.00, -28.00, -6.66, -26.66, -5.33, -25.33, -4.00, -24.00, -2.67, -22.67, -1.33,
    -21.33, 0.00, -20.00, 1.33, -18.67, 2.67, -17.33, 4.00, -16.00, 5.33, -14.67, 6.67, -13.33, 8.00, -12.00,
    9.33, -10.67, 10.67,
)  # fmt: skip

# ------------------------------------------------------------------------------------------------ VLP-16
# Velodyne VLP-16 user manual, "vertical angle" and "vertical correction (mm)" per laser ID 0-15 (its table of
# laser angles; the correction is added to z): (elevation deg, vertical origin offset mm).
_VLP16_LASERS = (
    (-15, 11.2), (1, -0.7), (-13, 9.7), (3, -2.2), (-11, 8.1), (5, -3.7), (-9, 6.6), (7, -5.1),
    (-7, 5.1), (9, -6.6), (-5, 3.7), (11, -8.1), (-3, 2.2), (13, -9.7), (-1, 0.7), (15, -11.2),
)  # fmt: skip

# ------------------------------------------------------------------------------------------------ VLP-32C
# Velodyne VLP-32C user manual, laser ID 0-31: (elevation deg, azimuth offset deg); non-uniform, densest at
# the horizon (1/3 deg).
_VLP32C_LASERS = (
    (-25, 1.4), (-1, -4.2), (-1.667, 1.4), (-15.639, -1.4), (-11.31, 1.4), (0, -1.4), (-0.667, 4.2),
    (-8.843, -1.4), (-7.254, 1.4), (0.333, -4.2), (-0.333, 1.4), (-6.148, -1.4), (-5.333, 4.2), (1.333, -1.4),
    (0.667, 4.2), (-4, -1.4), (-4.667, 1.4), (1.667, -4.2), (1, 1.4), (-3.667, -4.2), (-3.333, 4.2),
    (3.333, -1.4), (2.333, 1.4), (-2.667, -1.4), (-3, 1.4), (7, -1.4), (4.667, 1.4), (-2.333, -4.2),
    (-2, 4.2), (15, -1.4), (10.333, 1.4), (-1.333, -1.4),
)  # fmt: skip

# ------------------------------------------------------------------------------------------------ Ouster
# Ouster SDK design values for a gen1 OS-1-64 (ouster_client/src/types.cpp, gen1_altitude_angles and
# gen1_azimuth_angles, beam 0 the top one). Ouster computes the azimuth as encoder - beam_azimuth_angles, so the
# offset here is their negative.
_OS1_64_ALTITUDES = (
    16.611, 16.084, 15.557, 15.029, 14.502, 13.975, 13.447, 12.920, 12.393, 11.865, 11.338, 10.811, 10.283,
    9.756, 9.229, 8.701, 8.174, 7.646, 7.119, 6.592, 6.064, 5.537, 5.010, 4.482, 3.955, 3.428, 2.900, 2.373,
    1.846, 1.318, 0.791, 0.264,
)  # fmt: skip
_OS1_64_AZIMUTHS = (3.164, 1.055, -1.055, -3.164) * 16
# The SDK's lidar_origin_to_beam_origin_mm where a metadata file has none (firmware 1.14 and older):
# default_lidar_origin_to_beam_origin in ouster_core/src/sensor_info.cpp, by the prefix of prod_line ("OS-1-64"),
# 12.163 mm for any other ("default for gen 1").
OUSTER_BEAM_ORIGIN_MM = {"OS-0-": 27.67, "OS-1-": 15.806, "OS-2-": 13.762}
OUSTER_GEN1_BEAM_ORIGIN_MM = 12.163
OUSTER_OS1_BEAM_ORIGIN_MM = OUSTER_BEAM_ORIGIN_MM["OS-1-"]

# ------------------------------------------------------------------------------------------------ Pandar64
# Hesai Pandar64 design elevations, line 1 (top) to 64: pandarGeneral_elev_angle_map in
# github:HesaiTechnology/HesaiLidar_General_SDK src/PandarGeneralRaw/src/pandarGeneral_internal.cc. A real unit's
# angle-correction file (also per-line azimuth offsets, up to +-5.2 deg) replaces it: load it as a spec file.
_PANDAR64_ELEVATIONS = (
    14.882, 11.032, 8.059, 5.057, 3.04, 2.028, 1.86, 1.688, 1.522, 1.351, 1.184, 1.013, 0.846, 0.675, 0.508,
    0.337, 0.169, 0.0, -0.169, -0.337, -0.508, -0.675, -0.845, -1.013, -1.184, -1.351, -1.522, -1.688, -1.86,
    -2.028, -2.198, -2.365, -2.536, -2.7, -2.873, -3.04, -3.21, -3.375, -3.548, -3.712, -3.884, -4.05, -4.221,
    -4.385, -4.558, -4.72, -4.892, -5.057, -5.229, -5.391, -5.565, -5.726, -5.898, -6.061, -7.063, -8.059,
    -9.06, -9.885, -11.032, -12.006, -12.974, -13.93, -18.889, -24.897,
)  # fmt: skip


def laser_table(
    elevations_deg: Any, azimuth_offsets_deg: Any = None, beam_origins_m: Any = None
) -> dict[str, Any]:
    """A sensor's per-laser values (any laser order) as ``LidarSpec`` keyword arguments in ring order.

    Example:
        >>> laser_table([1.0, -1.0], azimuth_offsets_deg=[0.5, -0.5])
        {'elevations_deg': (-1.0, 1.0), 'azimuth_offsets_deg': (-0.5, 0.5)}
    """
    elevations = [float(v) for v in elevations_deg]
    order = sorted(range(len(elevations)), key=elevations.__getitem__)
    out: dict[str, Any] = {"elevations_deg": tuple(elevations[i] for i in order)}
    if azimuth_offsets_deg is not None:
        out["azimuth_offsets_deg"] = tuple(float(azimuth_offsets_deg[i]) for i in order)
    if beam_origins_m is not None:
        out["beam_origins_m"] = tuple(tuple(float(v) for v in beam_origins_m[i]) for i in order)
    return out


#: name -> ``LidarSpec`` keyword arguments (see the module docstring for the sources).
LIDAR_PRESETS: dict[str, dict[str, Any]] = {
    "paper": {"channels": 64, "points_per_channel": 2048, "hfov_deg": 270.0, "vfov_deg": (-45.0, 15.0)},
    # HDL-64E S2 datasheet: > 1.333 M points/s at 10 Hz over 64 lasers -> ~2083 per revolution; 120 m.
    "hdl64e": {
        "points_per_channel": 2083,
        "hfov_deg": 360.0,
        "max_range": 120.0,
        **laser_table(
            [v for _, v, _, _ in _HDL64E_LASERS],
            [a for a, _, _, _ in _HDL64E_LASERS],
            [(0.0, h / 100.0, z / 100.0) for _, _, z, h in _HDL64E_LASERS],
        ),
    },
    # HDL-32E: the manual's vertical angles (above), 100 m; nuScenes runs it at 20 Hz, ~1.39 M points/s -> 1084 per
    # laser and revolution (the nuScenes sweep of docs/figures/real_rings_nuscenes_hdl32e.json holds 32 x 1084).
    "hdl32e": {
        "points_per_channel": 1084,
        "hfov_deg": 360.0,
        "max_range": 100.0,
        **laser_table(HDL32E_VERTICAL_ANGLES_DEG),
    },
    "vlp16": {
        "points_per_channel": 1800,
        "hfov_deg": 360.0,
        "max_range": 100.0,
        **laser_table(
            [e for e, _ in _VLP16_LASERS], None, [(0.0, 0.0, mm / 1000.0) for _, mm in _VLP16_LASERS]
        ),
    },
    "vlp32c": {
        "points_per_channel": 1800,
        "hfov_deg": 360.0,
        "max_range": 200.0,
        **laser_table([e for e, _ in _VLP32C_LASERS], [a for _, a in _VLP32C_LASERS]),
    },
    "os1-64": {
        "points_per_channel": 1024,
        "hfov_deg": 360.0,
        "max_range": 120.0,
        **laser_table(
            _OS1_64_ALTITUDES + tuple(-v for v in reversed(_OS1_64_ALTITUDES)),
            [-a for a in _OS1_64_AZIMUTHS],
            [(OUSTER_OS1_BEAM_ORIGIN_MM / 1000.0, 0.0, 0.0)] * 64,
        ),
    },
    # OS1 rev 7 datasheet: 128 channels, 45 deg vertical FOV (+-22.5), uniform spacing; a unit's metadata JSON
    # (beam_altitude_angles, beam_azimuth_angles) is the exact table: load it with io.load_lidar_spec.
    "os1-128": {
        "channels": 128,
        "points_per_channel": 1024,
        "hfov_deg": 360.0,
        "vfov_deg": (-22.5, 22.5),
        "max_range": 120.0,
        "beam_origins_m": ((OUSTER_OS1_BEAM_ORIGIN_MM / 1000.0, 0.0, 0.0),) * 128,
    },
    # Pandar64 datasheet: 200 m, 0.2 deg at 10 Hz -> 1800 per revolution.
    "pandar64": {
        "points_per_channel": 1800,
        "hfov_deg": 360.0,
        "max_range": 200.0,
        **laser_table(_PANDAR64_ELEVATIONS),
    },
}


__all__ = [
    "HDL32E_VERTICAL_ANGLES_DEG",
    "LIDAR_PRESETS",
    "OUSTER_BEAM_ORIGIN_MM",
    "OUSTER_GEN1_BEAM_ORIGIN_MM",
    "OUSTER_OS1_BEAM_ORIGIN_MM",
    "laser_table",
]
