"""A reference given on a UTM grid with a rotation matrix of a FLU body (KAIST Complex Urban's
global_pose.csv: a 3x4 [R | t] in zone 52N a row) is read as the truth says: positions
written through PROJ (pyproj, nobody here wrote it), the attitude composed in closed form from
roll, pitch, heading, the grid's convergence measured from PROJ's grid lines."""
import math

import numpy as np
import pytest
import quaternion

from mimunav.importers import table
from mimunav.importers.recording import RecordingError

pyproj = pytest.importorskip("pyproj")

SPEC = """name = "utm"
[imu]
time = {{ file = "imu.csv", columns = [0], unit = "s" }}
angular_rate = {{ file = "imu.csv", columns = [1, 2, 3] }}
specific_force = {{ file = "imu.csv", columns = [4, 5, 6] }}
axes = "FRD"
[time]
unix_offset_s = 1500000000.0
[reference]
time = {{ file = "pose.csv", columns = [0], unit = "s" }}
position_utm = {{ file = "pose.csv", columns = [4, 8, 12], zone = 52, hemisphere = "N"{grid} }}
attitude_matrix = {{ file = "pose.csv", columns = [1, 2, 3, 5, 6, 7, 9, 10, 11] }}
body_axes = "FLU"
{extra}
"""


def _rz(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _dcm_nb(roll, pitch, heading):
    """Body FRD -> NED of the aerospace z-y-x angles (Titterton & Weston eq. 3.47)."""
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    return _rz(heading) @ np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]]) @ \
        np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])


def _poses(tmp_path, m=50):
    """pose.csv of m epochs 1.9 deg west of zone 52's meridian (convergence -1.15 deg) and a
    flat IMU file; returns (lat deg, lon deg, h m, C_nb) of each epoch."""
    rng = np.random.default_rng(3)
    lat = 37.4 + np.cumsum(rng.uniform(0, 2e-5, m))
    lon = 127.1 + np.cumsum(rng.uniform(0, 2e-5, m))
    h = 40.0 + rng.normal(0, 1, m)
    forward = pyproj.Transformer.from_crs("EPSG:4326", "EPSG:32652", always_xy=True)
    e, n = forward.transform(lon, lat)
    de, dn = (np.subtract(a, b) for a, b in zip(
        forward.transform(lon, lat + math.degrees(1.0 / 6.36e6)), (e, n)))
    gamma = -np.arctan2(de, dn)                     # grid north's bearing from true north
    enu_ned = np.array([[0.0, 1, 0], [1, 0, 0], [0, 0, -1]])
    frd_flu = np.diag([1.0, -1, -1])
    rows, dcms = [], []
    for k in range(m):
        c_nb = _dcm_nb(*rng.uniform(-0.2, 0.2, 2), rng.uniform(-math.pi, math.pi))
        r = _rz(gamma[k]) @ enu_ned @ c_nb @ frd_flu          # body FLU -> grid E, N, U
        pose = np.column_stack([r, [e[k], n[k], h[k]]]).ravel()
        rows.append([0.1 * k, *pose])
        dcms.append(c_nb)
    np.savetxt(tmp_path / "pose.csv", rows, delimiter=",", fmt="%.17g")
    t = np.arange(0.0, 0.1 * m, 0.01)
    imu = np.column_stack([t, np.zeros((len(t), 3)), np.tile([0.0, 0.0, -9.8], (len(t), 1))])
    np.savetxt(tmp_path / "imu.csv", imu, delimiter=",", fmt="%.9g")
    return lat, lon, h, np.array(dcms)


def _spec(tmp_path, grid="", extra=""):
    path = tmp_path / "spec.toml"
    path.write_text(SPEC.format(grid=grid, extra=extra))
    return path


def test_a_utm_pose_with_a_flu_rotation_matrix_is_the_truth(tmp_path):
    lat, lon, h, c_nb = _poses(tmp_path)
    rec = table.read(_spec(tmp_path))
    ref = rec.reference
    assert np.abs(np.degrees(ref["lat"]) - lat).max() * 111e3 < 1e-4      # m
    assert np.abs(np.degrees(ref["lon"]) - lon).max() * 88e3 < 1e-4
    assert np.abs(ref["h"] - h).max() < 1e-9
    got = quaternion.as_rotation_matrix(quaternion.from_float_array(ref["q_nb"]))
    assert np.abs(got - c_nb).max() < 1e-8     # the test's 1 m step measures gamma so far
    assert "UTM zone 52N" in rec.real["reference_utm"] and "-1.15" in rec.real["reference_utm"]


def test_a_utm_grid_or_a_matrix_not_said_whole_is_refused(tmp_path):
    _poses(tmp_path)
    spec = _spec(tmp_path)
    spec.write_text(spec.read_text().replace(', hemisphere = "N"', ""))
    with pytest.raises(RecordingError, match=r"position_utm needs its grid: .*hemisphere"):
        table.read(spec)
    with pytest.raises(RecordingError, match="body_axes names the vehicle's axes"):
        table.read(_spec(tmp_path, extra='attitude_of = "imu"'))
    rows = np.loadtxt(tmp_path / "pose.csv", delimiter=",")
    # a matrix written to 3 digits is a rotation to 1.4e-3: taken, made orthonormal (8 % of
    # a KAIST-like drive's rows had been refused as 'no rotation')
    rounded = rows.copy()
    rounded[:, [1, 2, 3, 5, 6, 7, 9, 10, 11]] = np.round(rounded[:, [1, 2, 3, 5, 6, 7, 9, 10,
                                                                    11]], 3)
    np.savetxt(tmp_path / "pose.csv", rounded, delimiter=",", fmt="%.17g")
    exact = table.read(_spec(tmp_path)).reference["q_nb"]
    np.savetxt(tmp_path / "pose.csv", rows, delimiter=",", fmt="%.17g")
    turned = quaternion.from_float_array(exact) * np.conjugate(quaternion.from_float_array(
        table.read(_spec(tmp_path)).reference["q_nb"]))
    angle = 2 * np.arccos(np.clip(np.abs(quaternion.as_float_array(turned)[:, 0]), 0, 1))
    assert np.degrees(angle).max() < 0.1                # q and -q alike
    rows[7, 1:4] *= 1.01                                        # a scaled first row
    np.savetxt(tmp_path / "pose.csv", rows, delimiter=",", fmt="%.17g")
    with pytest.raises(RecordingError, match=r"attitude_matrix row 7 is no rotation"):
        table.read(_spec(tmp_path))
