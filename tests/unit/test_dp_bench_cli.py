"""`constellation bench-scheduler --json` prints the contract keys (short horizon, tiny instances)."""

import json

from bringup.cli.main import main


def test_bench_scheduler_json(capsys):
    rc = main(["bench-scheduler", "--hours", "1", "--instances", "2", "--milp-gps", "8",
               "--milp-window-s", "30", "--json"])
    assert rc == 0
    r = json.loads(capsys.readouterr().out)
    for key in ("dp_over_milp_min", "dp_over_milp_mean", "instances", "dp_s_per_sat_6h", "horizon_fraction"):
        assert key in r
    assert r["instances"] == 2
    assert 0.9 <= r["dp_over_milp_min"] <= r["dp_over_milp_mean"] + 1e-12
    assert r["horizon_fraction"] > 0 and r["replans"] == 6


def test_bench_scheduler_bad_sat(capsys):
    assert main(["bench-scheduler", "--sat", "sat_99", "--json"]) == 2
    assert "sat_99" in capsys.readouterr().err
