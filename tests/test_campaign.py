"""Monte Carlo campaign: reproducible from its seed, resumable, the same on local processes
and on a (local) Dask cluster, refusing a results file of another campaign."""
import json

import numpy as np
import pytest

from mimunav import campaign

PROFILE = """name = "short"
description = "20 s: a 2 g pull-up and a roll"
[start]
latitude_deg = 30.0
longitude_deg = 104.0
height_m = 1000.0
speed_m_s = 200.0
heading_deg = 45.0
[[segment]]
kind = "pull"
load_factor = 2.0
flight_path_change_deg = 10.0
[[segment]]
kind = "roll"
rate_deg_s = 200.0
angle_deg = 360.0
[[segment]]
kind = "hold"
duration_s = 8.0
"""


@pytest.fixture(scope="module")
def profile(tmp_path_factory):
    path = tmp_path_factory.mktemp("campaign") / "short.toml"
    path.write_text(PROFILE)
    return str(path)


def _lines(path):
    return [json.loads(line) for line in open(path)]


def test_campaign_resumes_and_is_reproducible(profile, tmp_path):
    out = tmp_path / "a.jsonl"
    first = campaign.run_campaign(profile, 1, 7, str(out), workers=1, progress=False)
    assert len(_lines(out)) == 1
    with open(out, "a") as fh:
        fh.write('{"index": 1, "torn')                  # an interrupted write
    both = campaign.run_campaign(profile, 2, 7, str(out), workers=1, progress=False)
    assert [r["index"] for r in _lines(out)] == [0, 1]
    assert both[0] == first[0]                           # unit 0 was not recomputed
    for rec in both:             # each row is its own errors over the FOG-IMU's, per axis
        fog = np.abs(rec["fog"]["enu_m"])
        assert np.isfinite(fog).all() and fog.min() > 0
        for v in campaign.VARIANTS:
            row = rec["variants"][v]
            np.testing.assert_allclose(row["normalised_enu"], np.abs(row["enu_m"]) / fog,
                                       rtol=1e-12)
            assert row["norm_m"] == pytest.approx(float(np.linalg.norm(row["enu_m"])))
    again = campaign.run_campaign(profile, 2, 7, str(tmp_path / "b.jsonl"), workers=2,
                                  progress=False)
    assert again == both                                 # same seed, same numbers
    with pytest.raises(ValueError, match="another campaign"):
        campaign.run_campaign(profile, 2, 8, str(out), workers=1, progress=False)
    stats = campaign.summary(both)
    assert set(stats) == {"traditional", "entire", "FOG-IMU"}


def test_campaign_on_a_local_dask_cluster_matches_local_processes(profile, tmp_path):
    from dask.distributed import LocalCluster
    local = campaign.run_campaign(profile, 2, 3, str(tmp_path / "l.jsonl"), workers=2,
                                  progress=False)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                      dashboard_address=None) as cluster:
        remote = campaign.run_campaign(profile, 2, 3, str(tmp_path / "d.jsonl"),
                                       scheduler=cluster.scheduler_address, progress=False)
    assert remote == local


def test_in_memory_flight_equals_the_logged_one(profile, tmp_path):
    """The campaign's in-memory flight gives the table a written log gives."""
    from mimunav import evaluation, simulation
    from mimunav.profile import Profile
    prof = Profile.load(profile)
    log, _ = simulation.simulate_flight(prof, tmp_path / "f.mcap", 4, progress=False)
    unit, fog, rng_m, rng_f = simulation.flight_units(4)
    fm = simulation.flight_motion(prof, unit.mounting, unit.rate_hz, fog.mounting,
                                  fog.rate_hz, 100.0)
    mem = evaluation.Flight.from_simulation(fm, unit, fog, *simulation.record_flight(
        fm, unit, fog, rng_m, rng_f))
    cals = {"true": unit.coefficients}
    a = evaluation.table(evaluation.Flight.load(log), cals)
    b = evaluation.table(mem, cals)
    assert a["variants"]["true"]["enu_m"] == pytest.approx(b["variants"]["true"]["enu_m"],
                                                           rel=1e-9, abs=1e-9)
    assert a["fog"]["enu_m"] == pytest.approx(b["fog"]["enu_m"], rel=1e-9, abs=1e-9)
