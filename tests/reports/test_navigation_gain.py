"""The report's navigation with the found terms (`reports.navigation_gain`): not navigated
from an initial state the import leveled on the MIMU's own outputs when a found mounting
turns those outputs (the RTKLIB drive's 6 deg mounting had doubled the end error, 121 ->
250 km, and the report blamed the model's other errors)."""
from types import SimpleNamespace

import numpy as np

from mimunav.diagnosis.levels import leveled_on_its_outputs
from mimunav.reports.navigation_gain import navigation_gain, navigation_lines, tilting_mountings


def _recording(initial_state):
    from mimunav.frames.mounting import Mounting
    return SimpleNamespace(source="recording", truth=None, mimu_mounting=Mounting(), recording={
        "assumed": {"initial_state": initial_state}})


def test_a_found_mounting_is_not_navigated_from_a_self_leveled_state():
    leveled = _recording("level from the mean specific force over the rest 0.00-33.76 s; "
                         "heading from the GNSS course")
    whole = _recording("whole state from the reference at t = 0.00 s")
    assert leveled_on_its_outputs(leveled) and not leveled_on_its_outputs(whole)
    assert not leveled_on_its_outputs(SimpleNamespace(source="simulation", recording=None))
    t = np.linspace(0.0, 10.0, 11)
    err = np.column_stack([t, 0 * t, 0 * t])
    model = SimpleNamespace(result=lambda: (t, None, err))
    pitched = {"effect": "mounting_misalignment", "label": "mounting_misalignment imu.all",
               "vector_vehicle": [0.0044, -0.099, 0.107],        # the drive's, rad
               "vector_vehicle_ci95": [[-0.057, 0.066], [-0.161, -0.037], [0.054, 0.161]],
               "mounting_rpy_deg": [-179.95, 5.68, -173.85]}
    yawed = dict(pitched, vector_vehicle_ci95=[[-0.057, 0.066], [-0.06, 0.02], [0.054, 0.161]])
    assert tilting_mountings([yawed]) == []         # a turn about down leaves it level
    ((said, rpy),) = tilting_mountings([pitched])
    assert "-5.67 about the right" in said and rpy == [-179.95, 5.68, -173.85]
    found = SimpleNamespace(found=[{"effect": "mounting_misalignment", "sensor": "imu",
                                    "axis": "all"}])
    nav, _, series = navigation_gain(leveled, found, model, [pitched])   # never navigated
    assert "tilts the outputs the initial state was leveled on" in \
        nav["model+found"]["not_navigated"]
    assert "--mounting-rpy-deg -179.95 5.68 -173.85, to navigate" in \
        nav["model+found"]["not_navigated"]
    assert list(series) == ["model"] and nav["model"]["end_m"] == 10.0
    lines = "\n".join(navigation_lines({"navigation": nav, "level": "track"}))
    assert "| model | 10.0 |" in lines and "Not navigated with the found terms" in lines
    assert "| model+found |" not in lines and "The model's row" not in lines
    # a model written by an earlier diagnosis with a found mounting: its row says the tilt
    earlier = SimpleNamespace(found=[{"effect": "mounting_misalignment", "sensor": "imu",
                                      "axis": "all", "vector": [0.0, -0.1, 0.1]}])
    nav, _, _ = navigation_gain(leveled, found, model, [pitched], earlier)
    assert "-5.73 about the right" in nav["model"]["note"]
    assert "The model's row: its calibration holds a found mounting" in "\n".join(
        navigation_lines({"navigation": nav, "level": "track"}))


def test_the_imports_biases_leave_the_outputs_the_report_navigates():
    """A recording's outputs as recorded less the biases its import measured at a rest, as
    the navigation level and `windows` take them (a consumer unit's 0.5-1 deg/s gyro biases
    left in had tumbled the report's navigation to 4,016,748 m): all of them for the model
    and for the navigation level's findings, which lie beside them; with the sensor or track
    level's found constant bias on an axis, that finding alone - it is the whole bias."""
    from mimunav.reports.navigation_gain import import_biases
    flight = SimpleNamespace(mimu_raw=None, recording={
        "gyro_bias_static_rad_s": [0.01, -0.02, 0.03], "accel_bias_m_s2": [0.4, 0.1, -0.2]})
    gyro, accel = import_biases(flight)
    assert gyro.tolist() == [0.01, -0.02, 0.03] and accel.tolist() == [0.4, 0.1, -0.2]
    found = [{"effect": "bias_shift", "sensor": "gyro", "axis": "y"},
             {"effect": "bias_shift", "sensor": "accel", "axis": "x"},
             {"effect": "scale_factor", "sensor": "gyro", "axis": "z"}]
    gyro, accel = import_biases(flight, found, "sensor")
    assert gyro.tolist() == [0.01, 0.0, 0.03] and accel.tolist() == [0.0, 0.1, -0.2]
    gyro, accel = import_biases(flight, found, "navigation")
    assert gyro.tolist() == [0.01, -0.02, 0.03] and accel.tolist() == [0.4, 0.1, -0.2]
    assert flight.recording["gyro_bias_static_rad_s"] == [0.01, -0.02, 0.03]   # untouched
    raw = SimpleNamespace(mimu_raw=object(), recording=flight.recording)     # a raw log's
    assert [b.tolist() for b in import_biases(raw)] == [[0.0] * 3, [0.0] * 3]
