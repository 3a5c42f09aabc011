"""Tiny ``aeossp_standard`` cases written by the tests themselves, in the benchmark's file format.

Two sun-synchronous satellites made with ``sgp4init`` and exported as TLEs (``sgp4.exporter``),
a one-hour horizon from the TLE epoch, and tasks put on the first satellite's ground track
(``orbit_clock.frames.ecef_to_geodetic`` of its sub-satellite point at chosen instants).
"""

from __future__ import annotations

import math
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
import yaml
from sgp4.api import WGS72, Satrec, jday
from sgp4.exporter import export_tle

from orbit_clock.frames import ecef_to_geodetic, gmst_rad

EPOCH = datetime(2026, 3, 1, 0, 0, 0, tzinfo=UTC)


def tle(raan_deg: float, mean_anomaly_deg: float, satnum: int) -> tuple[str, str]:
    rec = Satrec()
    jd_epoch = (EPOCH - datetime(1949, 12, 31, tzinfo=UTC)).total_seconds() / 86400.0
    n_rev_day = 15.2  # ~ 500 km
    rec.sgp4init(WGS72, "i", satnum, jd_epoch, 2e-5, 0.0, 0.0, 1e-4, math.radians(0.0),
                 math.radians(97.4), math.radians(mean_anomaly_deg), n_rev_day * 2 * math.pi / 1440.0,
                 math.radians(raan_deg))
    return export_tle(rec)


def iso(s: float) -> str:
    return (EPOCH + timedelta(seconds=s)).strftime("%Y-%m-%dT%H:%M:%SZ")


def sat_entry(sid: str, l1: str, l2: str, sensor="visible", **res) -> dict:
    r = {"battery_capacity_wh": 1600.0, "initial_battery_wh": 1000.0, "idle_power_w": 25.0,
         "imaging_power_w": 480.0, "slew_power_w": 280.0, "sunlit_charge_power_w": 100.0}
    r.update(res)
    return {"satellite_id": sid, "norad_catalog_id": 90000, "tle_line1": l1, "tle_line2": l2,
            "sensor": {"sensor_type": sensor},
            "attitude_model": {"max_slew_velocity_deg_per_s": 1.0, "max_slew_acceleration_deg_per_s2": 0.25,
                               "settling_time_s": 3.0, "max_off_nadir_deg": 25.0},
            "resource_model": r}


def subsat(l1: str, l2: str, t_s: float) -> tuple[float, float]:
    rec = Satrec.twoline2rv(l1, l2)
    t = EPOCH + timedelta(seconds=t_s)
    jd, fr = jday(t.year, t.month, t.day, t.hour, t.minute, t.second)
    _e, r, _v = rec.sgp4(jd, fr)
    th = float(gmst_rad(jd, fr))
    x, y = math.cos(th) * r[0] + math.sin(th) * r[1], -math.sin(th) * r[0] + math.cos(th) * r[1]
    lat, lon, _alt = ecef_to_geodetic(np.array([x, y, r[2]]))
    return float(lat), float(lon)


def task_entry(tid: str, lat: float, lon: float, rel: float, due: float, dur=20, sensor="visible", w=1.0) -> dict:
    return {"task_id": tid, "name": tid, "latitude_deg": lat, "longitude_deg": lon, "altitude_m": 0.0,
            "release_time": iso(rel), "due_time": iso(due), "required_duration_s": dur,
            "required_sensor_type": sensor, "weight": w}


def write_case(folder: Path, sats: list[dict], tasks: list[dict], hours: float = 1.0) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    mission = {"mission": {"case_id": "tiny", "horizon_start": iso(0), "horizon_end": iso(hours * 3600),
                           "action_time_step_s": 5, "geometry_sample_step_s": 5, "resource_sample_step_s": 10,
                           "propagation": {"model": "sgp4"}}}
    (folder / "mission.yaml").write_text(yaml.safe_dump(mission))
    (folder / "satellites.yaml").write_text(yaml.safe_dump({"satellites": sats}))
    (folder / "tasks.yaml").write_text(yaml.safe_dump({"tasks": tasks}))
    return folder


def standard(folder: Path, **res) -> tuple[Path, tuple[str, str]]:
    """sat_a (visible) and sat_b (infrared, another plane); tasks on sat_a's track.

    t1 (weight 3) under sat_a at 600 s, t2 (2) at 640 s, t3 (1) 1.5 deg of longitude off the track at
    700 s, t4 infrared under sat_a at 900 s, t5 far away (the antipode of t1).
    """
    a = tle(10.0, 0.0, 90001)
    b = tle(40.0, 30.0, 90002)
    tasks = []
    for tid, ts, w, dlon, sensor in (("t1", 600, 3.0, 0.0, "visible"), ("t2", 640, 2.0, 0.0, "visible"),
                                     ("t3", 700, 1.0, 1.5, "visible"), ("t4", 900, 1.0, 0.0, "infrared")):
        lat, lon = subsat(*a, ts)
        tasks.append(task_entry(tid, lat, lon + dlon, ts - 300, ts + 300, sensor=sensor, w=w))
    lat, lon = subsat(*a, 600)
    tasks.append(task_entry("t5", -lat, lon + 180.0 if lon < 0 else lon - 180.0, 0, 3600))
    sats = [sat_entry("sat_a", *a, **res), sat_entry("sat_b", *b, sensor="infrared")]
    return write_case(folder, sats, tasks), a
