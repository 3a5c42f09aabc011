"""Real element sets for the catalogue tests (tests/unit/test_elements.py, tests/unit/test_fleet.py,
tests/system/test_catalogue_runs.py): CelesTrak's TLEs of the three Sentinel-2 satellites of
1 October 2026, transcribed, and writers of the same elements as TLE / 3LE and CCSDS OMM (XML, KVN,
CelesTrak's JSON, CSV)."""

from __future__ import annotations

import json
from pathlib import Path

S2 = [
    ("SENTINEL-2A", "1 40697U 15028A   26274.29857647 -.00000002  00000+0  15863-4 0  9990",
     "2 40697  98.5653 347.6046 0001070  85.9280 274.2026 14.30818852588907"),
    ("SENTINEL-2B", "1 42063U 17013A   26274.29142365 -.00000116  00000+0 -27532-4 0  9992",
     "2 42063  98.5698 347.5416 0001144  87.9623 272.1691 14.30816959499812"),
    ("SENTINEL-2C", "1 60989U 24157A   26273.97675974  .00000041  00000+0  32245-4 0  9999",
     "2 60989  98.5706 347.2366 0001210  82.3430 277.7890 14.30816519108113"),
]

# The same elements as OMM keywords, as CelesTrak writes them (the epoch to the microsecond)
OMM = [
    {"OBJECT_NAME": "SENTINEL-2A", "OBJECT_ID": "2015-028A", "EPOCH": "2026-10-01T07:09:57.007008",
     "MEAN_MOTION": "14.30818852", "ECCENTRICITY": ".000107", "INCLINATION": "98.5653", "RA_OF_ASC_NODE": "347.6046",
     "ARG_OF_PERICENTER": "85.928", "MEAN_ANOMALY": "274.2026", "EPHEMERIS_TYPE": "0", "CLASSIFICATION_TYPE": "U",
     "NORAD_CAT_ID": "40697", "ELEMENT_SET_NO": "999", "REV_AT_EPOCH": "58890", "BSTAR": "1.5863E-5",
     "MEAN_MOTION_DOT": "-2E-8", "MEAN_MOTION_DDOT": "0"},
    {"OBJECT_NAME": "SENTINEL-2B", "OBJECT_ID": "2017-013A", "EPOCH": "2026-10-01T06:59:39.003360",
     "MEAN_MOTION": "14.30816959", "ECCENTRICITY": ".0001144", "INCLINATION": "98.5698", "RA_OF_ASC_NODE": "347.5416",
     "ARG_OF_PERICENTER": "87.9623", "MEAN_ANOMALY": "272.1691", "EPHEMERIS_TYPE": "0", "CLASSIFICATION_TYPE": "U",
     "NORAD_CAT_ID": "42063", "ELEMENT_SET_NO": "999", "REV_AT_EPOCH": "49981", "BSTAR": "-2.7532E-5",
     "MEAN_MOTION_DOT": "-1.16E-6", "MEAN_MOTION_DDOT": "0"},
    {"OBJECT_NAME": "SENTINEL-2C", "OBJECT_ID": "2024-157A", "EPOCH": "2026-09-30T23:26:32.041536",
     "MEAN_MOTION": "14.30816519", "ECCENTRICITY": ".000121", "INCLINATION": "98.5706", "RA_OF_ASC_NODE": "347.2366",
     "ARG_OF_PERICENTER": "82.343", "MEAN_ANOMALY": "277.789", "EPHEMERIS_TYPE": "0", "CLASSIFICATION_TYPE": "U",
     "NORAD_CAT_ID": "60989", "ELEMENT_SET_NO": "999", "REV_AT_EPOCH": "10811", "BSTAR": "3.2245E-5",
     "MEAN_MOTION_DOT": "4.1E-7", "MEAN_MOTION_DDOT": "0"},
]

_META = ("OBJECT_NAME", "OBJECT_ID")
_MEAN = ("EPOCH", "MEAN_MOTION", "ECCENTRICITY", "INCLINATION", "RA_OF_ASC_NODE", "ARG_OF_PERICENTER", "MEAN_ANOMALY")
_TLE = ("EPHEMERIS_TYPE", "CLASSIFICATION_TYPE", "NORAD_CAT_ID", "ELEMENT_SET_NO", "REV_AT_EPOCH", "BSTAR",
        "MEAN_MOTION_DOT", "MEAN_MOTION_DDOT")


def write_tle(path: Path, three_line: bool = True, zero: bool = False) -> Path:
    lines = []
    for name, l1, l2 in S2:
        if three_line:
            lines.append(("0 " if zero else "") + name)
        lines += [l1, l2]
    path.write_text("\n".join(lines) + "\n")
    return path


def write_omm(path: Path, fmt: str, sets=OMM) -> Path:
    """The OMMs in CCSDS 502.0-B-3 XML, KVN, CelesTrak's JSON (numbers as numbers) or CSV."""
    if fmt == "json":
        doc = [{k: (v if k in ("OBJECT_NAME", "OBJECT_ID", "EPOCH", "CLASSIFICATION_TYPE") else
                    (int(v) if k in ("NORAD_CAT_ID", "ELEMENT_SET_NO", "REV_AT_EPOCH", "EPHEMERIS_TYPE")
                     else float(v))) for k, v in o.items()} for o in sets]
        path.write_text(json.dumps(doc, indent=1))
    elif fmt == "kvn":
        out = []
        for o in sets:
            out += ["CCSDS_OMM_VERS = 2.0", "CREATION_DATE = 2026-10-01T12:00:00", "ORIGINATOR = TEST",
                    "COMMENT written by tests/unit/test_elements.py"]
            out += [f"{k} = {o[k]}" for k in _META if k in o]
            out += ["CENTER_NAME = EARTH", "REF_FRAME = TEME", "TIME_SYSTEM = UTC", "MEAN_ELEMENT_THEORY = SGP4"]
            out += [f"{k} = {o[k]}" + (" [rev/day]" if k == "MEAN_MOTION" else " [deg]" if k == "INCLINATION" else "")
                    for k in _MEAN if k in o]
            out += [f"{k} = {o[k]}" for k in _TLE if k in o]
        path.write_text("\n".join(out) + "\n")
    elif fmt == "xml":
        segs = []
        for o in sets:
            meta = "".join(f"<{k}>{o[k]}</{k}>" for k in _META if k in o)
            mean = "".join(f"<{k}>{o[k]}</{k}>" for k in _MEAN if k in o)
            tle = "".join(f"<{k}>{o[k]}</{k}>" for k in _TLE if k in o)
            segs.append(f"<segment><metadata>{meta}<CENTER_NAME>EARTH</CENTER_NAME><REF_FRAME>TEME</REF_FRAME>"
                        f"<TIME_SYSTEM>UTC</TIME_SYSTEM><MEAN_ELEMENT_THEORY>SGP4</MEAN_ELEMENT_THEORY></metadata>"
                        f"<data><meanElements>{mean}</meanElements><tleParameters>{tle}</tleParameters></data></segment>")
        path.write_text('<?xml version="1.0" encoding="UTF-8"?>\n<ndm><omm id="CCSDS_OMM_VERS" version="2.0">'
                        "<header><CREATION_DATE>2026-10-01T12:00:00</CREATION_DATE><ORIGINATOR>TEST</ORIGINATOR></header>"
                        f"<body>{''.join(segs)}</body></omm></ndm>\n")
    elif fmt == "csv":
        keys = list(OMM[0])
        path.write_text(",".join(keys) + "\n" + "".join(",".join(o[k] for k in keys) + "\n" for o in sets))
    else:
        raise ValueError(fmt)
    return path
