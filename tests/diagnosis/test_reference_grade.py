"""A reference of any grade, and a recording's two halves (`sensors.accuracy.Accuracy`,
`diagnosis.confirmation.halves_check`): what the reference may carry itself is not charged to
the MIMU alone, and an interval the halves of a recording contradict is widened or set aside."""
import math
from types import SimpleNamespace

import numpy as np
import pytest
from scipy import stats

from mimunav.diagnosis import confirmation, inference, navigation
from mimunav.diagnosis.inference import Tier
from mimunav.sensors.accuracy import Accuracy
from mimunav.errors import InputError

DEG_H = math.pi / 180 / 3600


def test_a_reference_less_stable_than_table_4_is_of_mems_grade():
    assert not Accuracy().mems_grade
    vn = Accuracy.parse(f"gyro_bias={10 * DEG_H},gyro_step=0.01")
    assert vn.mems_grade
    # 2 sigma of its stability plus half a logging step: 0.005 rad/s of a 0.01 rad/s log
    assert vn.bias_allowance("gyro") == pytest.approx(2 * 10 * DEG_H + 0.005)
    assert vn.bias_sigma("gyro") == pytest.approx(math.hypot(10 * DEG_H, 0.01 / math.sqrt(12)))
    assert Accuracy().bias_sigma("accel") == pytest.approx(100e-6 * 9.80665)
    with pytest.raises(InputError, match="below 0.1 .scale 1, misalignment rad. or 1"):
        Accuracy.parse("gyro_step=2")


def test_the_grade_a_stated_accuracy_makes_is_said():
    """A rail trial's reference stated at 1.0004 deg/h made every finding `mimu-or-reference`
    with no word at import: the import now says which grade the diagnosis will take and why
    (a tactical unit is not called MEMS: it is treated as one)."""
    fog = Accuracy().grade_said()
    assert "gyro bias 1 deg/h" in fog and "within seed S1 Table 4's FOG-IMU" in fog
    stated = Accuracy.from_dict({"gyro_bias": 4.85e-6, "accel_bias": 1e-3}, "stated")
    said = stated.grade_said()
    assert "gyro bias 1.0004 deg/h" in said and "accelerometer bias 101.97 ug" in said
    assert "as it treats a MEMS-grade reference, whatever its class (a tactical unit too)" \
        in said and "--reference-accuracy" in said
    # only what lies beyond is named; 1 deg/h written 4.85e-6 rad/s is Table 4's, rounded
    # (it had made a glider's FOG-grade unit MEMS-grade, and its 1 m lever arm unfound)
    assert "(its accelerometer bias beyond 100 ug)" in said and "gyro bias beyond" not in said
    rounded = Accuracy.from_dict({"gyro_bias": 4.85e-6, "accel_bias": 9.8e-4}, "stated")
    assert not rounded.mems_grade and "within seed S1 Table 4's" in rounded.grade_said()
    assert Accuracy.from_dict({"gyro_bias": 4.9e-6}, "stated").mems_grade      # 1.01 deg/h


class _Halves:
    """A stand-in for `fitting.Fitter` that returns given (b, cov) per half."""
    values = {}

    def __init__(self, design, rows):
        self.half = "first" if rows[0] else "second"

    def fit(self, idx):
        return SimpleNamespace(of=lambda j: self.values[self.half])


@pytest.mark.parametrize("second, widened, kept", [
    (1.05, 1.0, True),          # the halves agree: the interval stands
    (1.6, None, True),          # they disagree, the widened interval still excludes zero
    (-1.0, None, False),        # they disagree in sign: inconclusive, set aside
])
def test_halves_that_disagree_widen_the_interval_or_set_the_term_aside(monkeypatch, second,
                                                                       widened, kept):
    design = SimpleNamespace(t=np.arange(100.0), terms=[{"effect": "scale_factor"}])
    monkeypatch.setattr(confirmation, "Fitter", _Halves)
    monkeypatch.setattr(confirmation, "position_of", lambda d, f: 0)
    se = 0.1
    _Halves.values = {"first": (np.array([1.0]), np.array([[se ** 2]])),
                      "second": (np.array([second]), np.array([[se ** 2]]))}
    finding = {"label": "scale_factor accel.x", "coefficient": 1.2, "p_heldout": 1e-6,
               "ci95": [1.2 - 1.96 * se, 1.2 + 1.96 * se]}
    found, aside = confirmation.halves_check(design, [finding])
    assert (len(found) == 1) == kept and (len(aside) == 1) == (not kept)
    out = (found or aside)[0]
    stat = (1.0 - second) ** 2 / (2 * se ** 2)
    factor = widened or math.sqrt(stat)
    assert out["halves"]["widened_by"] == pytest.approx(factor)
    half = 1.96 * se * factor
    assert out["ci95"] == pytest.approx([1.2 - half, 1.2 + half])
    if not kept:
        assert "halves disagree" in out["rejected"] and "inconclusive" in out["rejected"]
    if widened is None:     # one parameter: the held-out z (4.89 at p 1e-6) over the factor
        z = stats.norm.isf(0.5e-6) / factor
        assert out["halves"]["p_heldout_widened"] == pytest.approx(2 * stats.norm.sf(z),
                                                                   rel=1e-6)
        # with its own held-out limit, a finding the widening leaves above it is set aside
        # even where the interval still excludes zero (1.6: p 0.25 against 0.025)
        strict, aside = confirmation.halves_check(design, [dict(finding,
                                                               heldout_threshold=0.025)])
        assert (strict, len(aside)) == ([], 1) and "above its limit 0.025" in \
            aside[0]["rejected"]
    else:
        assert "p_heldout_widened" not in out["halves"]


def _velocity_tier(first, second, rng, sigma=0.02):
    """A navigation-level Tier of 600 one-second increments, one channel, whose residual is
    one candidate's column x times `first` in the first 300 s and `second` after, plus white
    noise of `sigma` (m/s)."""
    t = np.arange(1.0, 601.0)
    x = np.sin(2 * np.pi * t / 47.0) + 0.5 * np.sin(2 * np.pi * t / 13.0)
    truth = np.where(t <= 300.0, first, second)
    y = (x * truth + sigma * rng.standard_normal(len(t)))[:, None]
    return Tier("navigation", t, y, [{0: x[:, None]}], [1], kept=np.ones(len(t), bool),
                knot_s=(600.0,), block_s=30.0)


@pytest.mark.parametrize("second, kept, widened", [
    (0.2, True, False),         # one coefficient all through: the halves agree
    (0.3, True, True),          # it moves by half: widened, still beyond zero
    (-0.2, False, True),        # it changes sign: inconclusive
])
def test_the_navigation_levels_halves_see_a_term_that_moves_over_a_recording(second, kept,
                                                                            widened):
    """navigation.halves_check refits the found term on each half of the velocity-error
    increments: the halves' coefficients are the two truths (within 4 standard errors), and
    the verdict is the sensor level's. At a linearization point b0 (the relinearized
    findings), the tier's residual is what is left after b0, and the halves are b0 + their
    own fits."""
    rng = np.random.default_rng(7)
    held = (np.arange(600) // 60) % 2 == 1         # the diagnosis' odd segments
    for b0 in (None, 0.15):
        tier = _velocity_tier(0.2 - (b0 or 0.0), second - (b0 or 0.0), rng)
        fit_ho = inference.fit(tier, [0], held)
        lo, hi = (v[0] + (b0 or 0.0) for v in fit_ho.interval(0))
        finding = {"label": "scale_factor accel.x", "coefficient": float(fit_ho.beta[0]) +
                   (b0 or 0.0), "ci95": [float(lo), float(hi)]}
        point = None if b0 is None else [np.array([b0])]
        found, aside = navigation.halves_check(tier, [0], point, [finding], held)
        assert (len(found) == 1) == kept and (len(aside) == 1) == (not kept)
        out = (found or aside)[0]
        halves = out["halves"]
        se = [math.sqrt(fit.cov[0, 0]) for fit in (inference.fit(tier, [0], tier.t <= 300),)]
        assert halves["first"][0] == pytest.approx(0.2, abs=4 * se[0])
        assert halves["second"][0] == pytest.approx(second, abs=4 * se[0] * 1.5)
        assert (halves["widened_by"] > 1.0) == widened
        assert (out["ci95"][1] - out["ci95"][0]) == pytest.approx(
            (hi - lo) * halves["widened_by"], rel=1e-9)


def test_a_term_out_of_range_leaves_the_halves_of_the_others_in_place():
    """`navigation._within_range` drops a relinearized finding beyond its physical range
    together with its column and linearization point, so the halves of the terms kept are
    their own (an independent review: they had been paired with their neighbours')."""
    findings = [{"label": "a", "coefficient": 9.0, "units": "1", "effect": "scale_factor"},
                {"label": "b", "coefficient": 0.01, "units": "1", "effect": "scale_factor"}]
    kept, beyond, (tier, columns, point) = navigation._within_range(
        findings, lambda f: 0.05, ("tier", [4, 7], [np.array([9.0]), np.array([0.01])]))
    assert [f["label"] for f in kept] == ["b"] and columns == [7] and point[0][0] == 0.01
    assert beyond[0]["label"] == "a" and beyond[0]["beyond_range"] == 0.05
    assert navigation._within_range(findings[1:], lambda f: 0.05, ("tier", [7], None))[2][2] \
        is None


def test_terms_the_halves_set_aside_say_why_nothing_found_is_no_clean_bill():
    aside = {"label": "lever_arm imu.all", "halves": {"p_same": 1e-4, "widened_by": 3.0},
             "rejected": "the recording's halves disagree (p 0.0001): its interval widened "
                         "3.00x holds zero - inconclusive"}
    other = {"label": "x", "rejected": "held-out p = 0.5, needs < 0.025"}
    said = confirmation.set_aside_reasons([aside, other])
    assert said == [f"lever_arm imu.all: {aside['rejected']}"]


@pytest.mark.parametrize("bias_deg_h, stated, mems", [(1.0, False, False), (10.0, False, False),
                                                      (720.0, False, True),
                                                      (720.0, True, False)])
def test_a_default_fog_grade_the_references_rest_contradicts_is_mems_grade(bias_deg_h, stated,
                                                                           mems):
    """At the import's rest a FOG-IMU's gyros read the Earth's 15 deg/h within 1 deg/h (a
    tactical part's within 10): the default grade stands; a MEMS part's 0.2 deg/s (720
    deg/h) contradicts it - MEMS grade, its gyro bias stability the excess, said (a
    Shimmer's MEMS pair had had its couplings charged to the MIMU alone). A stated gyro bias
    is not overruled."""
    from mimunav.diagnosis.reference_grade import rest_graded
    from mimunav.frames.earth import OMEGA
    rng = np.random.default_rng(2)
    t = np.arange(0.0, 60.0, 0.01)
    earth = OMEGA * np.array([0.6, 0.0, -0.8])                 # its heading and latitude: any
    w = earth + bias_deg_h * DEG_H * np.array([0.0, 0.6, 0.8]) + rng.normal(0, 1e-3, (len(t), 3))
    w[t > 20.0] += 0.3                                         # it moves after its rest
    flight = SimpleNamespace(source="recording", recording={"static_s": [0.5, 19.5]}, fog_t=t,
                             fog_blocks=lambda: iter([(t, w, np.zeros_like(w))]))
    given = Accuracy.parse(f"gyro_bias={1 * DEG_H}") if stated else Accuracy()
    graded = rest_graded(flight, given)
    assert graded.mems_grade == mems, graded.source
    if mems:
        assert graded.gyro_bias == pytest.approx((bias_deg_h - 15.04) * DEG_H, rel=0.05)
        assert "the default FOG grade is contradicted" in graded.source
