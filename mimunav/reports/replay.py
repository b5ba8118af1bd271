"""The replay of a flight log as files: `mimunav replay`'s folder with nav.mcap (the MIMU's and
the FOG-IMU's navigation, NavState of the vehicle origin), summary.json (`mimunav-replay/2`:
end errors east/north/up in m and m/s, attitude error about north/east/down in rad) and
errors.png, written at once (`files.atomic_folder`)."""
import json
from pathlib import Path

import numpy as np

from ..compensation.calibration_file import Calibration
from ..evaluation.flight import Flight
from ..evaluation.replay import comparison_times, errors_at, ned_to_enu, replay, resample
from ..files import atomic_folder, refuse_folder_early, refuse_inputs
from ..flightlog import LogWriter
from ..flightlog import schemas as S
from ..frames import attitude
from .plots import Painter, navigation_errors

FILES = ("nav.mcap", "summary.json", "errors.png")


def write(log_path, cal_path, out_dir, end=None, nav_rate_hz=10.0, force=False):
    """Replay the log at `log_path` with the calibration file at `cal_path` (streamed: bounded
    memory) up to `end` (s since the log's epoch; default the last instant every channel
    covers) and write the folder `out_dir`, its NavState channels at nav_rate_hz; returns
    the summary (`mimunav-replay/2`)."""
    out = Path(out_dir)
    refuse_inputs([out], [log_path, cal_path])
    refuse_folder_early(out, force, FILES)
    with Painter() as painter:                  # forked now: matplotlib loads beside the work
        flight = Flight.load(log_path, stream=True)      # bounded memory
        cal = Calibration.load(cal_path)
        t = comparison_times(flight, end)
        t_nav = np.append(np.arange(t[0], t[-1], 1.0 / nav_rate_hz), t[-1])
        rep = replay(flight, cal, check="the calibration", at=np.union1d(t, t_nav))
        err = errors_at(rep, t)
        # the painter left first: the figure drawn before the folder commits, or the child
        # stopped before a failed folder is removed
        with atomic_folder(out, force=force, inputs=[log_path, cal_path]) as tmp, painter:
            series = {k: dict(v, t=t) for k, v in err.items() if k != "t"}
            navigation_errors(series, str(tmp / "errors.png"), f"{flight.name}: {cal_path}",
                              painter)
            with LogWriter(tmp / "nav.mcap") as log:
                for topic, traj in (("/mimu/nav", resample(rep.mimu, t_nav)),
                                    ("/fog/nav", resample(rep.fog, t_nav))):
                    log.write(topic, S.NAV_STATE, "vehicle",
                              flight.epoch_ns + np.round(traj.t * 1e9).astype(np.int64),
                              latitude=traj.lat, longitude=traj.lon, height=traj.h,
                              velocity_ned=traj.v_ned,
                              attitude_wxyz=attitude.as_wxyz(traj.q_nb))
            summary = summary_of(flight, log_path, cal_path, t, rep, err)
            (tmp / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    return summary


def summary_of(flight, log_path, cal_path, t, rep, err):
    """The `mimunav-replay/2` summary: the end errors of every pair (MIMU and FOG against the
    truth, MIMU against FOG) at the last comparison time t[-1], with the flags' counts."""
    return {"format": "mimunav-replay/2", "log": log_path, "calibration": cal_path,
            "end_t_s": float(t[-1]), "flags": rep.flags,
            "end": {k: {"position_enu_m": ned_to_enu(v["position"][-1]).tolist(),
                        "velocity_enu_m_s": ned_to_enu(v["velocity"][-1]).tolist(),
                        "attitude_ned_rad": v["attitude"][-1].tolist()}
                    for k, v in err.items() if k != "t"},
            "frames": "_enu: east, north, up; attitude_ned_rad: the attitude "
                      "error's rotation vector about north, east, down",
            "mimu_platform": (flight.mimu_platform.meta if flight.mimu_platform
                              else None)}
