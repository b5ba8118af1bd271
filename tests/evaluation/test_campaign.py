"""Monte Carlo campaign: reproducible from its seed, resumable, the same on local processes
and on a (local) Dask cluster, refusing a results file of another campaign."""
import dataclasses
import json
import types
from pathlib import Path

import numpy as np
import pytest

from mimunav.errors import InputError
from mimunav.evaluation import campaign
from profiles import PULL_UP_AND_ROLL

PROFILE = PULL_UP_AND_ROLL


@pytest.fixture(scope="module")
def profile(tmp_path_factory):
    path = tmp_path_factory.mktemp("campaign") / "short.toml"
    path.write_text(PROFILE)
    return str(path)


def _lines(path):
    return [json.loads(line) for line in open(path)]


@pytest.mark.slow
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
    other = campaign.Scenario(flight=profile, mimu_grade="tactical")      # same seed, other unit
    with pytest.raises(ValueError, match="another campaign"):
        campaign.run_campaign(other, 2, 7, str(out), workers=1, progress=False)
    namesake = tmp_path / "other" / "short.toml"           # same file name, other flight
    namesake.parent.mkdir()
    namesake.write_text(PROFILE.replace("duration_s = 8.0", "duration_s = 9.0", 1))
    assert namesake.read_text() != PROFILE
    with pytest.raises(ValueError, match="another campaign"):
        campaign.run_campaign(str(namesake), 2, 7, str(out), workers=1, progress=False)
    stats = campaign.summary(both)
    assert set(stats) == {"traditional", "entire", "FOG-IMU"}


@pytest.mark.slow
def test_campaign_computes_again_the_units_of_other_code_and_refuses_a_workers(profile, tmp_path,
                                                                             capsys):
    """A results file resumed after the simulator changed: its units made by other code
    (their `code` differs from `campaign.code_version()`) are computed again, with a
    warning, not mixed with this code's; a unit handed back by a worker running other code
    is refused before it is written."""
    out = tmp_path / "a.jsonl"
    first = campaign.run_campaign(profile, 1, 7, str(out), workers=1, progress=False)
    assert first[0]["code"] == campaign.code_version()
    old = dict(first[0], code="0123456789abcdef")
    old["variants"] = {v: dict(r, norm_m=-1.0) for v, r in old["variants"].items()}
    out.write_text(json.dumps(old) + "\n")
    again = campaign.run_campaign(profile, 1, 7, str(out), workers=1, progress=False)
    assert again == first and _lines(out) == first
    assert "1 unit(s) were made by other code" in capsys.readouterr().err
    from concurrent.futures import Future
    foreign = Future()
    foreign.set_result(dict(first[0], code="0123456789abcdef"))
    with pytest.raises(ValueError, match="other code"):
        campaign.run_campaign(profile, 1, 7, str(tmp_path / "b.jsonl"), progress=False,
                              futures=[foreign])
    assert _lines(tmp_path / "b.jsonl") == []


@pytest.mark.slow
def test_campaign_on_a_local_dask_cluster_and_a_callers_pool_matches_local_processes(profile, tmp_path):
    from dask.distributed import LocalCluster
    local = campaign.run_campaign(profile, 2, 3, str(tmp_path / "l.jsonl"), workers=2,
                                  progress=False)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                      dashboard_address=None) as cluster:
        remote = campaign.run_campaign(profile, 2, 3, str(tmp_path / "d.jsonl"),
                                       scheduler=cluster.scheduler_address, progress=False)
    assert remote == local
    # units submitted to the caller's pool beside its own work (`mimunav reproduce`)
    from concurrent.futures import ProcessPoolExecutor
    scenario = campaign.Scenario(flight=str(Path(profile).resolve()))
    with ProcessPoolExecutor(2, initializer=campaign.one_blas_thread) as pool:
        futures = campaign.submit_units(pool, scenario, 3, range(2))
        with pytest.raises(ValueError, match="submitted beforehand"):
            campaign.run_campaign(scenario, 3, 3, str(tmp_path / "x.jsonl"), futures=futures,
                                  progress=False)
        shared = campaign.run_campaign(scenario, 2, 3, str(tmp_path / "p.jsonl"),
                                       futures=futures, progress=False)
    assert shared == local
    assert [r["index"] for r in _lines(tmp_path / "p.jsonl")] in ([0, 1], [1, 0])


def test_in_memory_flight_equals_the_logged_one(profile, tmp_path):
    """The campaign's in-memory flight gives the table a written log gives."""
    from mimunav.sensors import simulation
    from mimunav.evaluation.flight import Flight
    from mimunav.evaluation.table import normalised_table
    from mimunav.motion.profile import Profile
    prof = Profile.load(profile)
    log, _ = simulation.simulate_flight(prof, tmp_path / "f.mcap", 4, progress=False)
    unit, fog, rng_m, rng_f = simulation.flight_units(4)
    fm = simulation.flight_motion(prof, unit.mounting, unit.rate_hz, fog.mounting,
                                  fog.rate_hz, 100.0)
    mem = Flight.from_simulation(fm, unit, fog, *simulation.record_flight(
        fm, unit, fog, rng_m, rng_f))
    cals = {"true": unit.coefficients}
    a = normalised_table(Flight.load(log), cals)
    b = normalised_table(mem, cals)
    assert a["variants"]["true"]["enu_m"] == pytest.approx(b["variants"]["true"]["enu_m"],
                                                           rel=1e-9, abs=1e-9)
    assert a["fog"]["enu_m"] == pytest.approx(b["fog"]["enu_m"], rel=1e-9, abs=1e-9)


def test_scenario_options_reach_the_unit_and_the_reference(profile):
    """Each option of a Scenario changes what it names and nothing else of the draw."""
    base = campaign.Scenario(flight=profile)
    u = base.draw_unit(5, "u")
    t = dataclasses.replace(base, mimu_grade="tactical").draw_unit(5, "u")
    assert t.noise.gyro_flicker == pytest.approx(np.radians(5.1 / 3600))
    assert u.noise.gyro_flicker == pytest.approx(np.radians(15 / 3600))
    assert t.coefficients.as_dict() == u.coefficients.as_dict()
    exact = dataclasses.replace(base, beyond_model=False).draw_unit(5, "u")
    assert exact.beyond_model == [] and u.beyond_model
    with pytest.raises(ValueError, match="MIMU grade"):
        campaign.Scenario(mimu_grade="perfect")
    with pytest.raises(ValueError, match="FOG grade"):
        campaign.Scenario(fog_grade="ring-laser")
    from mimunav.sensors.simulation import flight_units
    fogs = {g: flight_units(3, u, fog_grade=g)[1] for g in ("table4", "table4-bound")}
    assert fogs["table4-bound"].accuracy()["gyro_scale"] == 2.5e-4
    dev = {g: np.abs(np.diag(f.gyro_matrix) - 1) for g, f in fogs.items()}
    np.testing.assert_allclose(dev["table4-bound"], 2.5 * dev["table4"])   # same draw, scaled


@pytest.mark.slow
def test_a_pre_flight_gyro_zero_changes_the_traditional_zero_only(profile, monkeypatch):
    """--gyro-zero pre-flight: the traditional calibration's W0 is the one taken before
    take-off, its other coefficients the lab's; the entire calibration is the lab's. The
    choice needs a warm-up as long as the span it takes, is named in a campaign's identity
    (the lab zero as before: old campaigns resume), and is refused when unknown. The
    pre-flight zero is the default (issue 54: the paper's refs calibrate no gyro zero)."""
    pre = campaign.Scenario(flight=profile)
    assert pre.gyro_zero == "pre-flight"
    lab = dataclasses.replace(pre, gyro_zero="lab")
    assert "gyro_zero" not in lab.identity() and pre.identity()["gyro_zero"] == "pre-flight"
    with pytest.raises(ValueError, match="gyro zero"):
        campaign.Scenario(gyro_zero="hangar")
    with pytest.raises(ValueError, match="warm-up.*--gyro-zero lab"):
        campaign.Scenario(gyro_zero="pre-flight", warm_up_s=5.0)
    seen = []
    monkeypatch.setattr(campaign, "normalised_table",
                        lambda flight, cals, end=None: seen.append(cals) or {"log": None})
    for scenario in (lab, pre):
        campaign.run_unit(scenario, 1, 0)
    by_lab, by_pre = seen
    assert not np.allclose(by_lab["traditional"].W0, by_pre["traditional"].W0)
    np.testing.assert_array_equal(by_lab["traditional"].W1, by_pre["traditional"].W1)
    np.testing.assert_array_equal(by_lab["entire"].W0, by_pre["entire"].W0)


def test_regime_points_and_their_summary():
    """One-at-a-time points around the base (each level once, the base's not repeated), and
    the summary's medians and paper test on records whose ratios are known."""
    from mimunav.reports import regime
    pts = regime.points(campaign.Scenario())
    assert len(pts) == 1 + sum(len(v) - 1 for v in regime.LEVELS.values())
    assert len({p[2] for p in pts}) == len(pts)
    recs = []
    for k in range(1, 21):                     # FOG 1 m per axis; entire k/10, trad 10 k
        recs.append({"fog": {"enu_m": [1.0, -1.0, 1.0]}, "variants": {
            "entire": {"enu_m": [k / 10, -k / 10, 0.0 + k / 10]},
            "traditional": {"enu_m": [10.0 * k, 10.0 * k, -10.0 * k]}}})
    s = regime.point_summary(recs)
    np.testing.assert_allclose(s["entire"]["median"], [1.05] * 4)
    np.testing.assert_allclose(s["traditional"]["median"], [105.0] * 4)
    assert s["improvement_horizontal"] == pytest.approx(100.0)
    # units at or below the paper's row (2.78 / 0.3 / 6.69 and 3.6 / 24.1 / 9.07): entire
    # k / 10 <= 0.3 for k <= 3; traditional 10 k <= 24.1 for k <= 2
    rates = lambda v: [p["rate"] for p in s["paper"][v]]        # noqa: E731
    assert rates("entire") == [1.0, 3 / 20, 1.0] and rates("traditional") == [0.0, 2 / 20, 0.0]
    assert s["paper"]["order_of_magnitude"]["rate"] == 1.0      # 100x better in every unit
    assert s["paper"]["close_to_fog"]["k"] == 20                # entire k / 10 <= 3
    assert s["paper"]["both_words"]["k"] == 20
    lo, hi = s["paper"]["entire"][1]["ci95"]                    # Clopper-Pearson of 3 in 20
    assert lo == pytest.approx(0.0321, abs=1e-4) and hi == pytest.approx(0.3789, abs=1e-4)


def test_the_report_names_each_values_source_and_the_command_that_gives_it():
    from mimunav.reports.table3 import assumptions_markdown, command_line
    s = dataclasses.replace(campaign.Scenario(), mimu_grade="stim300", fog_grade="navigation",
                            warm_up_s=0.0, gyro_zero="lab")
    rows = {r.split("|")[1].strip(" `"): r for r in assumptions_markdown(s)[2:]}
    assert "STIM300" in rows["mimu_grade"] and "not the default" in rows["mimu_grade"]
    assert "not the paper's" in rows["fog_grade"]
    assert "given" in rows["warm_up_s"] and "not the default" not in rows["severity"]
    assert command_line(s, 3, 8) == ("mimunav reproduce --seed 3 --units 8 --warm-up-s 0.0 "
                                     "--mimu-grade stim300 --fog-grade navigation "
                                     "--gyro-zero lab")


def _broken_flight(*args, **kwargs):
    raise RuntimeError("the flight simulation broke")


@pytest.mark.slow
def test_reproduce_shares_one_pool_and_its_units_are_the_campaigns(profile, tmp_path,
                                                                    monkeypatch):
    """`mimunav reproduce` runs the drawn unit's lab and flight and the Monte Carlo's units on
    one pool: its units are those `run_unit` gives alone, written once each; the table's rows
    are there; a task that fails stops it with that error and no report."""
    from mimunav.reports import table3
    scenario = campaign.Scenario(flight=str(Path(profile).resolve()))
    md = table3.reproduce(tmp_path / "r", seed=5, mc_units=2, progress=False, force=True,
                          scenario=scenario)
    from threadpoolctl import threadpool_limits
    # as the pool's workers (`one_blas_thread`): a BLAS on 2 threads sums in another order
    # (1e-10 apart in the entire fit)
    with threadpool_limits(1):
        alone = [campaign.run_unit(scenario, 5, i) for i in range(2)]
    lines = sorted(_lines(tmp_path / "r" / "table3-campaign.jsonl"), key=lambda r: r["index"])
    assert lines == alone
    doc = json.load(open(tmp_path / "r" / "table3.json"))
    assert doc["campaign"] == json.loads(json.dumps(campaign.summary(alone)))
    assert set(doc["table"]["variants"]) == {"traditional", "entire", "true coefficients"}
    for part in (doc["table"], doc["budget"]):      # no path to a log that is gone
        assert part["log"] is None and "no log written" in part["log_note"]
    assert md.exists() and (tmp_path / "r" / "table3-entire.json").exists()
    monkeypatch.setattr(campaign, "fly", _broken_flight)
    with pytest.raises(RuntimeError, match="flight simulation broke"):
        table3.reproduce(tmp_path / "broken", seed=5, mc_units=2, progress=False,
                         scenario=scenario)
    assert not (tmp_path / "broken" / "table3.md").exists()


@pytest.mark.slow
def test_the_campaign_command_runs_a_unit_and_prints_its_table(profile, tmp_path, capsys):
    """The command's own glue (scenario options -> run_campaign -> summary), not only the
    library: a local once shadowed the scenario builder there."""
    from mimunav.cli.program import main
    out = tmp_path / "c.jsonl"
    assert main(["campaign", profile, "-o", str(out), "--units", "1", "--workers", "1"]) == 0
    printed = capsys.readouterr().out
    assert "Monte Carlo over 1 units" in printed and "| FOG-IMU | 1 | 1 | 1 |" in printed
    assert _lines(out)[0]["campaign"]["scenario"]["flight"] == "short.toml"


def test_the_regime_maps_ground_start_flights_begin_at_rest_long_enough_to_align():
    """The start's points fly profiles a ground start accepts: at rest from the first sample
    for at least the alignment's span (`evaluation.ground.ALIGN_S`)."""
    import tomllib
    from mimunav import FLIGHTS
    from mimunav.evaluation.ground import ALIGN_S
    from mimunav.reports import regime
    for name in regime.START_FLIGHTS:
        doc = tomllib.loads((FLIGHTS / name).read_text())
        first = doc["segment"][0]
        assert doc["start"]["speed_m_s"] == 0.0
        assert first["kind"] == "hold" and first["duration_s"] >= ALIGN_S


def test_the_start_effect_is_read_from_its_pair_of_points():
    from mimunav.reports import regime

    def row(start, trad, ent):
        return {"option": "start", "level": start,
                "name": f"flight=boost-coast, start={start}",
                "traditional": {"median": [0, 0, 0, trad]}, "entire": {"median": [0, 0, 0, ent]}}
    said = regime.start_effect([row("air", 500.0, 40.0), row("ground", 3.0, 1.2)])
    assert len(said) == 1
    assert "traditional 500 -> 3, entire 40 -> 1.2" in said[0]
    assert regime.start_effect([row("air", 500.0, 40.0)]) == []      # no pair, no sentence


def test_where_the_papers_rows_are_reached_is_read_from_the_units_shares():
    """A row is reached where half the units or more lie at or below it in east and north;
    the point is named with how it differs from the base (a key the base's identity leaves
    out is a non-default value); a row reached nowhere is said so."""
    from mimunav.reports import regime

    def row(name, option, scenario, trad, ent):
        rates = lambda r: [{"rate": x} for x in r]                           # noqa: E731
        return {"option": option, "name": name, "scenario": scenario,
                "paper": {"traditional": rates(trad), "entire": rates(ent)}}
    base = {"flight": "high-dynamic.toml", "flight_sha256": "a"}
    said = regime.rows_reached([
        row("base", None, base, (0.0, 0.0, 0.1), (0.1, 0.0, 0.4)),
        row("ground", "start", {"flight": "boost-coast.toml", "flight_sha256": "b",
                                "start": "ground"}, (0.56, 0.88, 0.25), (0.88, 0.12, 0.8)),
        row("up only", "x", dict(base, severity=0.5), (0.0, 0.5, 1.0), (0.0, 0.0, 1.0))])
    assert said[0].endswith("at: `ground` (away from the base in flight boost-coast.toml, "
                            "start ground).")
    assert said[1].endswith("at: no point of this map.")


def test_the_g_sensitivity_factor_scales_the_drawn_unit_and_is_said():
    from mimunav.reports.table3 import command_line
    tripled = dataclasses.replace(campaign.Scenario(), g_sensitivity=3.0)
    c1 = campaign.Scenario().draw_unit(2, "u").coefficients
    c3 = tripled.draw_unit(2, "u").coefficients
    np.testing.assert_array_equal(c3.C, 3.0 * c1.C)
    np.testing.assert_array_equal(c3.W1, c1.W1)                 # nothing else moves
    assert tripled.identity()["g_sensitivity"] == 3.0
    assert "g_sensitivity" not in campaign.Scenario().identity()    # old campaigns resume
    assert command_line(tripled, 1, 16).endswith("--g-sensitivity 3.0")
    with pytest.raises(InputError, match="g-sensitivity factor -1"):
        campaign.Scenario(g_sensitivity=-1.0)


def test_a_duration_ends_the_same_flight_earlier_and_is_said(monkeypatch):
    """`duration_s` takes the end point that long after the navigators' start, on the same
    flight (the table's own `end`); 0 is the flight's end and leaves old campaigns' identity
    as it was; a duration beyond the profile is refused."""
    from mimunav.reports.table3 import command_line
    short = dataclasses.replace(campaign.Scenario(), duration_s=30.0)
    assert short.identity()["duration_s"] == 30.0
    assert "duration_s" not in campaign.Scenario().identity()
    assert command_line(short, 1, 16).endswith("--duration-s 30.0")
    ends = []
    monkeypatch.setattr(campaign, "normalised_table",
                        lambda flight, cals, end=None: ends.append((flight.initial.t, end)) or {
                            "log": None})
    monkeypatch.setattr(campaign, "lab_calibration", lambda *a, **k: None)
    monkeypatch.setattr(campaign, "traditional_zero", lambda cal, still: cal)
    flight = types.SimpleNamespace(initial=types.SimpleNamespace(t=4.0))
    monkeypatch.setattr(campaign, "fly", lambda scenario, unit, useed: (flight, None))
    campaign.run_unit(short, 1, 0)
    campaign.run_unit(campaign.Scenario(), 1, 0)
    assert ends == [(4.0, 34.0), (4.0, None)]
    with pytest.raises(InputError, match="duration 500.0 s"):
        campaign.Scenario(duration_s=500.0)         # the base flight lasts 144 s
    # from the pad the navigators start 120 s in: boost-coast's 363 s leave 243
    pad = dict(flight=str(campaign.FLIGHTS / "boost-coast.toml"), start="ground")
    assert campaign.Scenario(**pad, duration_s=200.0).duration_s == 200.0
    with pytest.raises(InputError, match="less than the 243 s the navigators fly"):
        campaign.Scenario(**pad, duration_s=300.0)
