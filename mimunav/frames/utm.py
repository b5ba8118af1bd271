"""Universal Transverse Mercator grid coordinates on the WGS-84 ellipsoid, to geodetic
latitude and longitude, with the grid's meridian convergence.

A UTM zone (1-60) is a transverse Mercator projection about its central meridian
lon0 = 6 zone - 183 deg, scaled by K0 = 0.9996 on it, with a false easting of 500 km and a
false northing of 10 000 km south of the equator. The grid's axes are not true east and north
away from lon0: grid north lies the convergence gamma clockwise of true north (about
(lon - lon0) sin(lat): +1.2 deg at 2 deg east of lon0, 37 N), so a heading or an attitude
given in the grid's axes turns by gamma into true ones.

The inverse is Krueger's series in the third flattening n to n^3 (Karney, "Transverse
Mercator with an accuracy of a few nanometers", J. Geodesy 85, 2011: the grid to the conformal
sphere, eqs. 11, 14-15, the coefficients' first three terms as the Wikipedia's UTM article
states them), then the conformal latitude to the geodetic one by Newton's method on
Karney's eqs. 7-8 (exact, where that series' next term would leave 0.4 mm): within a zone,
0.02 mm from PROJ's (tests/frames).
"""
import math

import numpy as np

from .earth import A, E2, F

K0 = 0.9996                     # scale on the central meridian
FALSE_EASTING = 500e3           # m
FALSE_NORTHING_SOUTH = 10e6     # m, the southern hemisphere's
N3 = F / (2 - F)                # the third flattening n
RECTIFYING = A / (1 + N3) * (1 + N3 ** 2 / 4 + N3 ** 4 / 64)     # A of the series, m
BETA = (N3 / 2 - 2 * N3 ** 2 / 3 + 37 * N3 ** 3 / 96,              # grid -> conformal sphere
        N3 ** 2 / 48 + N3 ** 3 / 15,
        17 * N3 ** 3 / 480)


def central_meridian(zone):
    """The central meridian (rad) of UTM zone `zone` (1-60)."""
    return math.radians(6 * zone - 183)


def to_geodetic(easting, northing, zone, north=True):
    """(latitude rad, longitude rad, convergence rad) of UTM grid coordinates easting and
    northing (m, arrays) in `zone` (1-60) of the northern (north=True) or southern
    hemisphere. The convergence gamma is the bearing of grid north from true north,
    clockwise: a heading from grid north plus gamma is the heading from true north."""
    xi = (np.asarray(northing, float) - (0.0 if north else FALSE_NORTHING_SOUTH)) / \
        (K0 * RECTIFYING)
    eta = (np.asarray(easting, float) - FALSE_EASTING) / (K0 * RECTIFYING)
    xi_p, eta_p, sigma_p, tau_p = xi.copy(), eta.copy(), np.ones_like(xi), np.zeros_like(xi)
    for j, b in enumerate(BETA, start=1):
        xi_p -= b * np.sin(2 * j * xi) * np.cosh(2 * j * eta)
        eta_p -= b * np.cos(2 * j * xi) * np.sinh(2 * j * eta)
        sigma_p -= 2 * j * b * np.cos(2 * j * xi) * np.cosh(2 * j * eta)
        tau_p += 2 * j * b * np.sin(2 * j * xi) * np.sinh(2 * j * eta)
    chi = np.arcsin(np.sin(xi_p) / np.cosh(eta_p))            # the conformal latitude
    lat = geodetic_latitude(chi)
    lon = central_meridian(zone) + np.arctan2(np.sinh(eta_p), np.cos(xi_p))
    t = np.tan(xi_p) * np.tanh(eta_p)
    gamma = np.arctan2(tau_p + sigma_p * t, sigma_p - tau_p * t)
    return lat, lon, gamma


def geodetic_latitude(chi):
    """The geodetic latitude (rad) of conformal latitudes chi (rad): tau = tan(lat) solved
    from tau' = tan(chi) = tau sqrt(1 + sigma^2) - sigma sqrt(1 + tau^2), sigma =
    sinh(e atanh(e tau / sqrt(1 + tau^2))) (Karney 2011, eq. 7), by Newton's method with its
    derivative (eq. 8); from tau = tau', five steps reach double precision."""
    e = math.sqrt(E2)
    target = np.tan(chi)
    tau = target.copy()
    for _ in range(5):
        root = np.hypot(1.0, tau)
        sigma = np.sinh(e * np.arctanh(e * tau / root))
        tau_p = tau * np.hypot(1.0, sigma) - sigma * root
        slope = (1 - E2) * np.hypot(1.0, tau_p) * root / (1 + (1 - E2) * tau ** 2)
        tau = tau + (target - tau_p) / slope
    return np.arctan(tau)
