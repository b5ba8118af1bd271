"""The traditional row's budget (`evaluation.traditional`): its five groups telescope to the
unit's true outputs, each relative to where the zeros were set."""
import numpy as np
import pytest

from mimunav.compensation.model import compensate
from mimunav.evaluation import campaign
from profiles import PULL_UP_AND_ROLL
from mimunav.evaluation.traditional import (GROUPS, ZeroConditions, added_back,
                                            gravity_reaction, traditional_budget)
from mimunav.frames import earth

PROFILE = PULL_UP_AND_ROLL


@pytest.fixture(scope="module")
def flown(tmp_path_factory):
    """A drawn unit (Table 2 coefficients, g-sensitivity included) on the 20 s pull-up and
    roll, with its zeros set at made-up conditions away from the flight's."""
    path = tmp_path_factory.mktemp("traditional") / "short.toml"
    path.write_text(PROFILE)
    scenario = campaign.Scenario(flight=str(path), gyro_zero="lab")
    unit = scenario.draw_unit(3, "u")
    flight, _ = campaign.fly(scenario, unit, 3)
    zero = ZeroConditions(np.array([31.0, 33.0, 29.0]),
                          flight.mimu_raw["gyro_frequency"].mean(axis=0) * (1 + 2e-4),
                          np.array([0.5, -0.3, -9.7]))
    return flight, unit.coefficients, zero


def _outputs(cal, raw):
    f, w, _ = compensate(cal, raw["accel_volts"], raw["gyro_volts"], raw["accel_temperature"],
                         raw["gyro_frequency"], filter_outliers=False)
    return f, w


def test_the_five_groups_telescope_to_the_true_outputs(flown):
    """A calibration equal to the true one's linear part with its zeros set at `zero` (eqs.
    2/4 frozen there; W0 holding C times the zeros' specific force) plus the five groups is
    the true calibration, sample by sample - so no group is counted twice or left out."""
    flight, true, zero = flown
    trad = true.without(("C", "A2", "A3", "W2", "W3")).frozen_at(zero.accel_temperature,
                                                                  zero.gyro_frequency)
    trad.W0 = trad.W0 + true.C @ zero.gyro_specific_force
    groups = added_back(flight, true, zero)
    assert list(groups) == list(GROUPS)
    f, w = _outputs(trad, flight.mimu_raw)
    f_true, w_true = _outputs(true, flight.mimu_raw)
    np.testing.assert_allclose(f + sum(g[0] for g in groups.values()), f_true, rtol=0, atol=1e-9)
    np.testing.assert_allclose(w + sum(g[1] for g in groups.values()), w_true, rtol=0, atol=1e-12)
    # each group is what it says: the 1 g part sees only the attitude, not the pull-up's load
    assert all(np.any(g[1] != 0) for g in groups.values())
    rest = gravity_reaction(flight)
    g = earth.normal_gravity(flight.truth.lat[0], flight.truth.h[0])
    np.testing.assert_allclose(np.linalg.norm(rest, axis=1), g, rtol=1e-3)
    np.testing.assert_allclose(groups["g-sensitivity at 1 g"][1],
                               (rest - zero.gyro_specific_force) @ true.C.T)


@pytest.mark.slow
def test_all_five_added_back_navigate_as_the_true_coefficients(flown):
    """The budget's '+ all five' row navigates to the true calibration's end error, and each
    group's worth is the traditional row's 3-D error minus its own."""
    from mimunav.evaluation.table import normalised_table
    flight, true, zero = flown
    trad = true.without(("C", "A2", "A3", "W2", "W3")).frozen_at(zero.accel_temperature,
                                                                  zero.gyro_frequency)
    trad.W0 = trad.W0 + true.C @ zero.gyro_specific_force
    doc = traditional_budget(flight, trad, true, zero)
    table = normalised_table(flight, {"true": true})
    np.testing.assert_allclose(doc["variants"]["+ all five"]["enu_m"],
                               table["variants"]["true"]["enu_m"], atol=1e-6)
    base = doc["variants"]["traditional"]["norm_m"]
    for name in GROUPS:
        row = doc["variants"][f"+ {name}"]
        assert row["worth_m"] == pytest.approx(base - row["norm_m"])
