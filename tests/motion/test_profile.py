"""Flight profiles: the commanded manoeuvres are what the motion flies."""
import math

import numpy as np
import pytest

from mimunav.motion import truth
from mimunav.motion.profile import G0, Profile, ProfileError
from test_truth import _profile
from places import FLIGHTS


def test_segments_reach_their_commanded_values():
    prof = _profile([
        {"kind": "accelerate", "accel_g": 30.0, "to_speed_m_s": 600.0, "ramp_s": 0.1},
        {"kind": "roll", "rate_deg_s": 400.0, "angle_deg": -270.0},
        {"kind": "turn", "load_factor": 9.0, "heading_change_deg": 135.0},
        {"kind": "climb", "flight_path_deg": 20.0, "load_factor": 5.0, "duration_s": 3.0},
        {"kind": "coast", "duration_s": 1.0}])
    m = prof.motion()
    speed, path, heading, bank = m.channels([prof.duration])[0]
    assert speed == pytest.approx(600.0, abs=1e-9)
    assert math.degrees(heading) == pytest.approx(135.0, abs=1e-9)
    assert math.degrees(bank) == pytest.approx(-270.0, abs=1e-9)
    assert path == pytest.approx(0.0, abs=1e-12)
    t = np.linspace(0, prof.duration, 200001)
    ch = m.channels(t)
    assert np.degrees(ch[:, 1]).max() == pytest.approx(20.0, abs=1e-9)
    rate = np.gradient(ch, t, axis=0)
    assert rate[:, 0].max() == pytest.approx(30 * G0, rel=1e-6)
    assert np.degrees(-rate[:, 3]).max() == pytest.approx(400.0, rel=1e-6)


def test_steady_turn_is_coordinated_at_the_load_factor():
    n = 6.0
    prof = _profile([{"kind": "turn", "load_factor": n, "heading_change_deg": 180.0,
                      "roll_rate_deg_s": 100.0}], speed_m_s=250.0)
    t = np.arange(0, int(prof.duration * 1000) + 1) / 1000
    run = truth.generate(prof.motion(), t)
    mid = len(t) // 2
    f = run.dv[mid] * 1000
    # specific force along body -z with magnitude n g (Earth rate/curvature: < 2e-3 rel.)
    assert -f[2] / (n * G0) == pytest.approx(1.0, rel=2e-3)
    assert abs(f[1]) < 2e-3 * n * G0 and abs(f[0]) < 1e-3


@pytest.mark.parametrize("segment, message", [
    ({"kind": "turn", "load_factor": 0.5, "heading_change_deg": 90}, "load_factor > 1"),
    ({"kind": "pull", "load_factor": 0.5, "flight_path_change_deg": 10}, "cannot change"),
    ({"kind": "warp", "duration_s": 1}, "unknown kind"),
    ({"kind": "hold"}, "duration_s"),
    ({"kind": "accelerate", "accel_g": 1, "to_speed_m_s": 100}, "not reached"),
    ({"kind": "climb", "flight_path_deg": 89, "duration_s": 1}, r"outside \[-85, 85\]"),
    ({"kind": "turn", "load_factor": 9, "heading_change_deg": 1}, "too small"),
])
def test_bad_segments_are_refused_with_the_reason(segment, message):
    with pytest.raises(ProfileError, match=message):
        _profile([segment])


def test_shipped_profiles_load_and_span_their_regimes(tmp_path):
    flights = FLIGHTS
    static = Profile.load(flights / "static.toml")
    assert static.duration == 3600.0 and static.start["speed"] == 0.0
    hd = Profile.load(flights / "high-dynamic.toml")
    t = np.arange(0, int(hd.duration * 200) + 1) / 200
    run = truth.generate(hd.motion(), t)
    assert np.linalg.norm(run.dv, axis=1).max() * 200 / G0 == pytest.approx(30.0, abs=0.1)
    assert np.degrees(np.linalg.norm(run.dtheta, axis=1).max() * 200) == pytest.approx(400, abs=1)
    bad = tmp_path / "bad.toml"
    bad.write_text("name = 'x'\n[start\n")
    with pytest.raises(ProfileError, match="not valid TOML"):
        Profile.load(bad)


def test_severity_scales_the_g_exposure_and_rates_and_keeps_the_manoeuvres(tmp_path):
    """A profile flown at severity s: peak longitudinal acceleration and roll rate x s, the
    steady turn's specific force 1 + s (n - 1) g; headings, bank and speed reached kept."""
    from mimunav.motion.profile import scale_severity
    doc = {"name": "p", "start": {"latitude_deg": 30.0, "longitude_deg": 0.0, "height_m": 1e3,
                                  "speed_m_s": 250.0, "heading_deg": 0.0},
           "segment": [{"kind": "accelerate", "accel_g": 20.0, "to_speed_m_s": 400.0},
                       {"kind": "roll", "rate_deg_s": 300.0, "angle_deg": 360.0},
                       {"kind": "turn", "load_factor": 9.0, "heading_change_deg": 180.0}]}
    s = 0.5
    full, mild = Profile.from_dict(doc), Profile.from_dict(scale_severity(doc, s))
    assert mild.name == "p@0.5" and doc["segment"][0]["accel_g"] == 20.0   # input untouched
    for prof, k in ((full, 1.0), (mild, s)):
        m = prof.motion()
        t = np.linspace(0, prof.duration, 400001)
        ch = m.channels(t)
        rate = np.gradient(ch, t, axis=0)
        assert rate[:, 0].max() == pytest.approx(20 * G0 * k, rel=1e-4)
        assert np.degrees(np.abs(rate[:, 3])).max() == pytest.approx(300.0 * k, rel=1e-4)
        end = m.channels([prof.duration])[0]
        assert end[0] == pytest.approx(400.0) and math.degrees(end[2]) == pytest.approx(180.0)
    assert mild.duration > full.duration
    n = 1 + s * (9.0 - 1)                        # the turn's load factor at severity s
    tt = np.arange(0, int(mild.duration * 200) + 1) / 200
    run = truth.generate(mild.motion(), tt)
    f = -run.dv[:, 2] * 200 / G0                 # body -z specific force, g
    assert f.max() == pytest.approx(n, rel=3e-3)
    with pytest.raises(ProfileError, match="severity"):
        scale_severity(doc, 0.0)
