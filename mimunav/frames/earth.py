"""WGS-84 Earth model: ellipsoid, rotation, normal gravity, radii, frames.

Frames: ECEF (e, Earth-centred Earth-fixed), NED (n, local north-east-down at the
point's geodetic latitude/longitude). Geodetic positions: latitude and longitude in rad,
height above the ellipsoid in m.

Constants and the normal-gravity formulas are those of NIMA TR8350.2 (3rd ed., 2000),
"Department of Defense World Geodetic System 1984", chapter 3 and 4.
"""
import math

import numpy as np
from numpy.typing import ArrayLike

from ..kernels import njit

A = 6378137.0                        # semi-major axis, m                 (TR8350.2 tab 3.1)
F = 1 / 298.257223563                # flattening                          (tab 3.1)
OMEGA = 7.292115e-5                  # Earth rotation rate, rad/s          (tab 3.1)
GM = 3.986004418e14                  # gravitational constant, m^3/s^2     (tab 3.1)
B = A * (1 - F)                      # semi-minor axis, m
E2 = F * (2 - F)                     # first eccentricity squared
GAMMA_E = 9.7803253359               # normal gravity at the equator, m/s^2 (tab 3.4)
K_SOMIGLIANA = 0.00193185265241      # Somigliana constant                 (tab 3.4)
M_RATIO = OMEGA**2 * A**2 * B / GM   # m = w^2 a^2 b / GM                  (tab 3.4)


@njit(inline="always")
def gravity_from_sin2(s2: ArrayLike, h: ArrayLike) -> np.ndarray:
    """Normal gravity, m/s^2, from sin^2(lat) and h (m): the core of `normal_gravity`, for
    scalars in the navigator's kernel (numba) and arrays through its `py_func` (numpy)."""
    g0 = GAMMA_E * (1.0 + K_SOMIGLIANA * s2) * (1.0 / np.sqrt(1.0 - E2 * s2))
    return g0 * (1.0 - 2.0 / A * (1.0 + F + M_RATIO - 2.0 * F * s2) * h + 3.0 * h * h / (A * A))


@njit(inline="always")
def radii_from_sin2(s2: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """(R_N, R_E), m, from sin^2(lat): the core of `radii` (scalars in numba, arrays through
    its `py_func`). One division: 1/sqrt(w2), which is also gravity's (`gravity_from_sin2`)
    and is computed once where both are inlined in one kernel."""
    w2 = 1.0 - E2 * s2
    per_w = 1.0 / np.sqrt(w2)
    r_e = A * per_w
    return r_e * (1.0 - E2) * (per_w * per_w), r_e


def _sin2(lat):
    return np.sin(np.asarray(lat, dtype=float)) ** 2


def normal_gravity(lat: ArrayLike, h: ArrayLike) -> np.ndarray:
    """Magnitude of normal gravity (gravitation + centrifugal), m/s^2; lat rad, h m (scalars
    or arrays that broadcast).

    Somigliana's closed formula on the ellipsoid (TR8350.2 eq. 4-1) with the second-order
    Taylor expansion in height above it (TR8350.2 eq. 4-3):
        g(lat, h) = g0(lat) * (1 - 2/a (1 + f + m - 2 f sin^2 lat) h + 3 h^2 / a^2)
    It acts along the ellipsoid normal (NED +z, down).
    """
    return gravity_from_sin2.py_func(_sin2(lat), np.asarray(h, dtype=float))


def meridian_radius(lat: ArrayLike) -> np.ndarray:
    """Meridian (north-south) radius of curvature R_N = a (1 - e^2) / (1 - e^2 sin^2)^1.5, m."""
    return radii_from_sin2.py_func(_sin2(lat))[0]


def prime_vertical_radius(lat: ArrayLike) -> np.ndarray:
    """Prime-vertical (east-west) radius of curvature R_E = a / (1 - e^2 sin^2)^0.5, m."""
    return radii_from_sin2.py_func(_sin2(lat))[1]


def radii(lat: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """(R_N, R_E): meridian and prime-vertical radii of curvature, m."""
    return radii_from_sin2.py_func(_sin2(lat))


@njit(inline="always")
def nav_rates(lat: float, h: float, vn: float, ve: float) -> tuple:
    """Scalar core: `nav_rates_at` at latitude lat (rad) - its last two values are the
    position rates per unit velocity, not the radii (`radii` gives those)."""
    return nav_rates_at(math.sin(lat), math.cos(lat), h, vn, ve)


@njit(inline="always")
def nav_rates_at(sl: float, cl: float, h: float, vn: float, ve: float) -> tuple:
    """Scalar core: Earth rate w_ie^n and transport rate w_en^n in NED (rad/s), gravity
    (m/s^2, down) and the position rates per unit velocity, at the latitude whose sine and
    cosine are sl, cl, at height h (m), moving with NED velocity (vn, ve) m/s.
    Returns (ie_n, ie_d, en_n, en_e, en_d, g, per_n, per_e); ie_e is zero;
    per_n = 1/(R_N + h) (rad/m: dlat/dt = vn per_n), per_e = 1/((R_E + h) cos lat)
    (dlon/dt = ve per_e). Four divisions in all, radii and gravity included (the divider's
    throughput bounds the navigator's kernel)."""
    s2 = sl * sl
    r_n, r_e = radii_from_sin2(s2)
    per_n = 1.0 / (r_n + h)
    per_re = 1.0 / (r_e + h)
    per_cl = 1.0 / cl
    en_n = ve * per_re
    return (OMEGA * cl, -OMEGA * sl, en_n, -vn * per_n, -en_n * sl * per_cl,
            gravity_from_sin2(s2, h), per_n, per_re * per_cl)


def earth_rate_ned(lat: ArrayLike) -> np.ndarray:
    """Earth rotation rate w_ie expressed in NED, rad/s, shape (..., 3)."""
    lat = np.asarray(lat, dtype=float)
    return OMEGA * np.stack([np.cos(lat), np.zeros_like(lat), -np.sin(lat)], axis=-1)


def transport_rate_ned(lat: ArrayLike, h: ArrayLike, v_ned: ArrayLike) -> np.ndarray:
    """Transport rate w_en (rotation of NED relative to ECEF) in NED, rad/s, shape (..., 3).

    w_en = [v_E/(R_E+h), -v_N/(R_N+h), -v_E tan(lat)/(R_E+h)]  (Titterton & Weston eq. 3.71)
    """
    r_n, r_e = radii(lat)
    v_ned = np.asarray(v_ned, dtype=float)
    ve = v_ned[..., 1] / (r_e + h)
    return np.stack([ve, -v_ned[..., 0] / (r_n + h), -ve * np.tan(lat)], axis=-1)


def gravity_ned(lat: ArrayLike, h: ArrayLike) -> np.ndarray:
    """Normal-gravity vector in NED, m/s^2, shape (..., 3): (0, 0, g(lat, h))."""
    g = np.asarray(normal_gravity(lat, h), dtype=float)
    return np.stack([np.zeros_like(g), np.zeros_like(g), g], axis=-1)


def geodetic_to_ecef(lat: ArrayLike, lon: ArrayLike, h: ArrayLike) -> np.ndarray:
    """Geodetic (rad, rad, m) -> ECEF coordinates, m, shape (..., 3)."""
    sl, cl = np.sin(lat), np.cos(lat)
    r_e = A / np.sqrt(1 - E2 * sl**2)
    return np.stack([(r_e + h) * cl * np.cos(lon),
                     (r_e + h) * cl * np.sin(lon),
                     (r_e * (1 - E2) + h) * sl], axis=-1)


def ecef_to_geodetic(r_e: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ECEF coordinates (m, shape (..., 3)) -> (lat rad, lon rad, h m).

    Exact closed form of Heikkinen (1982), as given by Zhu (1993), valid away from the
    Earth's centre.
    """
    r_e = np.asarray(r_e, dtype=float)
    x, y, z = r_e[..., 0], r_e[..., 1], r_e[..., 2]
    ep2 = (A**2 - B**2) / B**2
    p = np.hypot(x, y)
    f_ = 54 * B**2 * z**2
    g_ = p**2 + (1 - E2) * z**2 - E2 * (A**2 - B**2)
    c = E2**2 * f_ * p**2 / g_**3
    s = np.cbrt(1 + c + np.sqrt(c**2 + 2 * c))
    k = s + 1 + 1 / s
    p_ = f_ / (3 * k**2 * g_**2)
    q = np.sqrt(1 + 2 * E2**2 * p_)
    r0 = -p_ * E2 * p / (1 + q) + np.sqrt(
        0.5 * A**2 * (1 + 1 / q) - p_ * (1 - E2) * z**2 / (q * (1 + q)) - 0.5 * p_ * p**2)
    u = np.hypot(p - E2 * r0, z)
    v = np.sqrt((p - E2 * r0) ** 2 + (1 - E2) * z**2)
    z0 = B**2 * z / (A * v)
    h = u * (1 - B**2 / (A * v))
    lat = np.arctan2(z + ep2 * z0, p)
    lon = np.arctan2(y, x)
    return lat, lon, h


def ned_to_ecef_matrix(lat: ArrayLike, lon: ArrayLike) -> np.ndarray:
    """Direction-cosine matrix C_en that maps NED vectors to ECEF, shape (..., 3, 3)."""
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    return np.stack([np.stack([-sl * co, -so, -cl * co], axis=-1),
                     np.stack([-sl * so, co, -cl * so], axis=-1),
                     np.stack([cl, np.zeros_like(cl), -sl], axis=-1)], axis=-2)


def ned_difference(lat: ArrayLike, lon: ArrayLike, h: ArrayLike, lat_ref: ArrayLike, lon_ref: ArrayLike,
                   h_ref: ArrayLike) -> np.ndarray:
    """Position of (lat, lon, h) relative to a reference point, in the reference's NED, m.

    Exact (through ECEF), so it serves for position errors of any size.
    """
    d_e = geodetic_to_ecef(lat, lon, h) - geodetic_to_ecef(lat_ref, lon_ref, h_ref)
    c_en = ned_to_ecef_matrix(lat_ref, lon_ref)
    return np.einsum("...ji,...j->...i", c_en, d_e)


def ned_offset_to_geodetic(d_ned: ArrayLike, lat_ref: ArrayLike, lon_ref: ArrayLike,
                           h_ref: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inverse of `ned_difference`: the point at NED offset d_ned (m, (..., 3)) from a
    reference point -> (lat rad, lon rad, h m); exact through ECEF."""
    c_en = ned_to_ecef_matrix(lat_ref, lon_ref)
    r_e = geodetic_to_ecef(lat_ref, lon_ref, h_ref) + np.einsum("ij,...j->...i", c_en, d_ned)
    return ecef_to_geodetic(r_e)
