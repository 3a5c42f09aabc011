"""Progress when the output is not a terminal (bringup/cli/run.py ``_progress_display``): periodic
one-line reports on stderr - a run under nohup, CI or `| tee` is not silent for minutes."""

from __future__ import annotations

import re

from bringup.cli.run import _progress_display

H = 6 * 3600 * 10**9


def test_lines_at_every_tenth_and_period(capsys):
    prog, update = _progress_display(True, H, terminal=False, period_s=3600.0)
    assert prog is None
    for k in range(101):
        update(t_ns=k * H // 100, rtf=240.0, extra="12 msgs")
    lines = capsys.readouterr().err.strip().splitlines()
    # a line each time a new tenth of the horizon is reached (the period is an hour: never by time)
    assert len(lines) == 10, lines
    assert lines[0].startswith("run: sim 0:36:00 of 6:00:00 (10.0 %), 240x real time, 12 msgs")
    assert lines[-1].startswith("run: sim 6:00:00 of 6:00:00 (100.0 %)")
    assert all(re.match(r"^run: sim \d+:\d\d:\d\d of 6:00:00 \(\d+\.\d %\)", ln) for ln in lines)


def test_lines_by_wall_time_and_none_when_hidden(capsys):
    _, update = _progress_display(True, H, terminal=False, period_s=0.0)
    update(t_ns=1, rtf=None)
    update(t_ns=2, rtf=None)
    assert len(capsys.readouterr().err.strip().splitlines()) == 2
    _, quiet = _progress_display(False, H, terminal=False, period_s=0.0)
    quiet(t_ns=H // 2, rtf=1.0)
    assert capsys.readouterr().err == ""


def test_a_terminal_gets_the_bar():
    prog, _ = _progress_display(True, H, terminal=True)
    assert prog is not None
