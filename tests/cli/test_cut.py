"""`mimunav cut`: a log cut to a span, so that a message that tells the user to cut names a
command that does it. The cut keeps every channel's messages inside the span, the metadata,
and an initial state inside it (the reference's there), and the cut log navigates."""
import numpy as np
import pytest

from mimunav.cli import main
from mimunav.evaluation.flight import Flight
from mimunav.evaluation.replay import comparison_times, errors_at, replay
from mimunav.flightlog import FlightLog
from mimunav.motion.profile import Profile
from mimunav.sensors.mimu import MimuUnit
from mimunav.sensors.simulation import simulate_flight
from places import FLIGHTS


@pytest.mark.slow
def test_a_cut_log_holds_the_span_and_navigates_from_the_reference_state(tmp_path):
    unit = MimuUnit.draw(3)
    path = tmp_path / "gentle.mcap"
    profile = Profile.load(FLIGHTS / "gentle.toml")
    profile.segments = profile.segments[:3]         # coast, climb, turn: 100-160 s inside
    simulate_flight(profile, path, seed=3, unit=unit, progress=False)
    out = tmp_path / "cut.mcap"
    assert main(["cut", str(path), "--span", "100:160", "-o", str(out)]) == 0
    with FlightLog(out) as log:
        meta = log.metadata()
        epoch = int(meta["flight"]["epoch_unix_ns"])
        for topic in ("/mimu/raw", "/fog/imu", "/truth/state"):
            t = (log.read(topic, fields=())["log_time"].astype(np.int64) - epoch) / 1e9
            assert 100.0 <= t[0] < 100.01 and 159.99 < t[-1] <= 160.0, topic
        assert meta["cut"]["span_s"] == [100.0, 160.0]
    flight = Flight.load(out)
    assert flight.initial.t == pytest.approx(100.0)
    whole = Flight.load(path)
    k = np.searchsorted(whole.truth.t, 100.0)
    assert flight.initial.lat == whole.truth.lat[k] and flight.initial.h == whole.truth.h[k]
    err = errors_at(replay(flight, unit.coefficients), comparison_times(flight))
    # 60 s of a Table 4 FOG-IMU from the reference state: metres (a wrong start: kilometres)
    assert np.abs(err["fog-truth"]["position"][-1]).max() < 10.0
    assert main(["cut", str(path), "--span", "100:160", "-o", str(out)]) == 2   # not over it


def test_a_span_without_a_start_is_refused(tmp_path):
    from mimunav.flightlog import LogWriter
    from mimunav.flightlog import schemas as S
    path = tmp_path / "bare.mcap"
    with LogWriter(path) as log:
        log.metadata("flight", {"epoch_unix_ns": "0", "initial_state": {"t": 0.0}})
        t = np.arange(1, 101) * 10_000_000
        log.write("/mimu/imu", S.IMU, "mimu", t, **S.imu_fields(np.zeros((100, 3)),
                                                                np.zeros((100, 3))))
    assert main(["cut", str(path), "--span", "0.5:0.9", "-o", str(tmp_path / "o.mcap")]) == 2
    assert not (tmp_path / "o.mcap").exists()
