"""Earth model against published WGS-84 values and independent geometry."""
import numpy as np
import pytest

from mimunav.frames import earth


def test_normal_gravity_matches_wgs84_equator_and_pole():
    # NIMA TR8350.2 table 3.4: gamma_e = 9.7803253359, gamma_p = 9.8321849378 m/s^2
    assert earth.normal_gravity(0.0, 0.0) == pytest.approx(9.7803253359, abs=1e-10)
    assert earth.normal_gravity(np.pi / 2, 0.0) == pytest.approx(9.8321849378, abs=1e-9)


def test_free_air_gradient_is_the_textbook_value():
    # free-air gradient about -0.3086 mGal/m = -3.086e-6 s^-2 at mid latitudes
    lat = np.radians(45.0)
    grad = (earth.normal_gravity(lat, 100.0) - earth.normal_gravity(lat, -100.0)) / 200.0
    assert grad == pytest.approx(-3.086e-6, rel=2e-3)


def test_radii_at_equator_and_pole():
    r_n, r_e = earth.radii(0.0)
    assert r_n == pytest.approx(earth.A * (1 - earth.E2), rel=1e-15)
    assert r_e == pytest.approx(earth.A, rel=1e-15)
    r_n, r_e = earth.radii(np.pi / 2)
    assert r_n == pytest.approx(earth.A / np.sqrt(1 - earth.E2), rel=1e-15)
    assert r_e == pytest.approx(r_n, rel=1e-15)


def test_geodetic_ecef_round_trip_and_known_points():
    rng = np.random.default_rng(0)
    lat = rng.uniform(-np.pi / 2 + 1e-6, np.pi / 2 - 1e-6, 10000)
    lon = rng.uniform(-np.pi, np.pi, 10000)
    h = rng.uniform(-1e3, 1e5, 10000)
    lat2, lon2, h2 = earth.ecef_to_geodetic(earth.geodetic_to_ecef(lat, lon, h))
    assert np.abs(lat2 - lat).max() < 1e-14 * 10
    assert np.abs(np.angle(np.exp(1j * (lon2 - lon)))).max() < 1e-14 * 10
    assert np.abs(h2 - h).max() < 1e-7
    np.testing.assert_allclose(earth.geodetic_to_ecef(0.0, 0.0, 0.0), [earth.A, 0, 0])
    np.testing.assert_allclose(earth.geodetic_to_ecef(np.pi / 2, 0.0, 0.0), [0, 0, earth.B],
                               atol=1e-9)


def test_ned_difference_is_arc_length_for_small_steps():
    lat, lon, h = np.radians(30.0), 0.2, 500.0
    r_n, r_e = earth.radii(lat)
    d = earth.ned_difference(lat + 1e-6, lon, h, lat, lon, h)
    assert d[0] == pytest.approx((r_n + h) * 1e-6, rel=1e-6)
    d = earth.ned_difference(lat, lon + 1e-6, h, lat, lon, h)
    east = (r_e + h) * np.cos(lat) * 1e-6
    assert d[1] == pytest.approx(east, rel=1e-6)
    assert d[2] == pytest.approx(east**2 / (2 * (r_e + h)), rel=1e-2)   # the Earth curves away
    d = earth.ned_difference(lat, lon, h - 3.0, lat, lon, h)
    np.testing.assert_allclose(d, [0, 0, 3.0], atol=1e-9)


def test_transport_rate_is_the_rotation_rate_of_ned_along_a_path():
    # independent: differentiate C_en along a path and compare with w_en
    lat0, lon0, h = np.radians(50.0), 0.1, 2000.0
    v = np.array([150.0, -80.0, 0.0])
    r_n, r_e = earth.radii(lat0)
    dt = 1e-3
    dlat, dlon = v[0] / (r_n + h) * dt, v[1] / ((r_e + h) * np.cos(lat0)) * dt
    c0 = earth.ned_to_ecef_matrix(lat0 - dlat / 2, lon0 - dlon / 2)
    c1 = earth.ned_to_ecef_matrix(lat0 + dlat / 2, lon0 + dlon / 2)
    skew = earth.ned_to_ecef_matrix(lat0, lon0).T @ (c1 - c0) / dt   # C_ne dC_en/dt = [w_en x]
    w = np.array([skew[2, 1], skew[0, 2], skew[1, 0]])
    np.testing.assert_allclose(w, earth.transport_rate_ned(lat0, h, v), rtol=1e-6, atol=1e-12)


def test_geodesy_against_pymap3d():
    """An implementation nobody here wrote (pymap3d, WGS-84): geodetic <-> ECEF and the local
    NED offset, at random points from the poles to 100 km up and 100 km apart."""
    import pymap3d as pm
    rng = np.random.default_rng(11)
    lat = rng.uniform(-1.55, 1.55, 500)
    lon = rng.uniform(-np.pi, np.pi, 500)
    h = rng.uniform(-500.0, 1e5, 500)
    ours = earth.geodetic_to_ecef(lat, lon, h)
    theirs = np.column_stack(pm.geodetic2ecef(lat, lon, h, deg=False))
    assert np.abs(ours - theirs).max() < 1e-6
    back = np.column_stack(pm.ecef2geodetic(*ours.T, deg=False))
    lat2, lon2, h2 = earth.ecef_to_geodetic(theirs)
    assert np.abs(lat2 - back[:, 0]).max() < 1e-12 and np.abs(h2 - back[:, 2]).max() < 1e-5
    assert np.abs(np.angle(np.exp(1j * (lon2 - back[:, 1])))).max() < 1e-12
    lat0, lon0, h0 = lat + rng.uniform(-0.01, 0.01, 500), lon + rng.uniform(-0.01, 0.01, 500), h / 2
    ned = earth.ned_difference(lat, lon, h, lat0, lon0, h0)
    ref = np.column_stack(pm.geodetic2ned(lat, lon, h, lat0, lon0, h0, deg=False))
    assert np.abs(ned - ref).max() < 1e-5


def test_normal_gravity_above_the_ellipsoid_follows_the_grs80_series():
    """GRS80 (Moritz, J. Geodesy 74:128, 2000): gamma_h = gamma - (3.087691 - 0.004398
    sin^2 phi) 1e-6 h + 0.72125e-12 h^2 (m/s^2, h in m); WGS-84's constants differ from
    GRS80's by parts in 1e9 in these coefficients. At 10 km the three terms are 3.1e-2,
    4.4e-5 and 7.2e-5 m/s^2: the free-air gradient's latitude term and the h^2 term are
    each checked to 2 %."""
    for lat_deg in (0.0, 45.0, 90.0):
        lat = np.radians(lat_deg)
        for h in (5e3, 1e4, 2e4):
            got = earth.normal_gravity(lat, h) - earth.normal_gravity(lat, 0.0)
            s2 = np.sin(lat) ** 2
            expect = -(3.087691 - 0.004398 * s2) * 1e-6 * h + 0.72125e-12 * h * h
            assert abs(got - expect) < 0.02 * (0.004398e-6 * h + 0.72125e-12 * h * h) + 1e-7, \
                (lat_deg, h, got, expect)


def test_gravity_vector_has_the_documented_shape_for_arrays():
    """gravity_ned(lat, h) is (..., 3) with g along NED down, for arrays as for scalars."""
    lat = np.radians([0.0, 30.0, 60.0, 90.0])
    g = earth.gravity_ned(lat, np.full(4, 100.0))
    assert g.shape == (4, 3)
    np.testing.assert_array_equal(g[:, :2], 0.0)
    np.testing.assert_allclose(g[:, 2], earth.normal_gravity(lat, 100.0), rtol=0, atol=0)
