"""UTM grid coordinates to geodetic ones (`frames.utm`) against PROJ (pyproj: an implementation
nobody here wrote) over whole zones of both hemispheres, and the grid's convergence against
the bearing of PROJ's own grid lines measured by finite differences."""
import math

import numpy as np
import pytest

from mimunav.frames import utm

pyproj = pytest.importorskip("pyproj")


@pytest.mark.parametrize("zone, north", [(52, True), (33, False), (1, True), (60, False)])
def test_grid_to_geodetic_agrees_with_proj_to_a_tenth_of_a_millimetre(zone, north):
    rng = np.random.default_rng(zone)
    lat = rng.uniform(0.0, 84.0, 3000) * (1 if north else -1)
    lon = 6 * zone - 183 + rng.uniform(-3.5, 3.5, 3000)      # a zone's width and its edges
    forward = pyproj.Transformer.from_crs("EPSG:4326", f"EPSG:{32600 + zone + (0 if north else 100)}",
                                          always_xy=True)
    e, n = forward.transform(lon, lat)
    lat_u, lon_u, gamma = utm.to_geodetic(e, n, zone, north)
    north_m = (np.degrees(lat_u) - lat) * 111.2e3
    east_m = ((np.degrees(lon_u) - lon + 180) % 360 - 180) * 111.3e3 * np.cos(np.radians(lat))
    assert np.abs(north_m).max() < 1e-4 and np.abs(east_m).max() < 1e-4
    # the convergence: the bearing of grid north from true north, clockwise - a step 1 m
    # true north moves on PROJ's grid by (dE, dN), at bearing -gamma from grid north
    de, dn = (np.subtract(x1, x0) for x1, x0 in zip(
        forward.transform(lon, lat + math.degrees(1.0 / 6.36e6)), (e, n)))
    measured = -np.arctan2(de, dn)
    assert np.abs(gamma - measured).max() < 1e-6              # the step's own curvature
    # and its size as the textbook's first term says: (lon - lon0) sin(lat) near it
    near = np.abs(lon - (6 * zone - 183)) < 0.5
    assert np.allclose(gamma[near], np.radians(lon - (6 * zone - 183))[near]
                       * np.sin(np.radians(lat[near])), atol=2e-5)
