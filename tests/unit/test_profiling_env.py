"""bringup/engine/ros/profiling.py: with AGILE_DTN_PROFILE_DIR a node process's profile is written
to DIR/<role>.prof when it ends (readable by pstats, holding the code that ran); without the
variable nothing is started or written."""

import pstats

from bringup.engine.ros import profiling


def _work() -> int:
    return sum(i * i for i in range(20000))


def test_profile_written_where_the_variable_says(tmp_path, monkeypatch):
    monkeypatch.setenv(profiling.ENV_PROFILE_DIR, str(tmp_path / "prof"))
    assert profiling.start("sat_11")
    assert not profiling.start("sat_11")  # one profile per process
    _work()
    path = profiling.dump()
    assert path == tmp_path / "prof" / "sat_11.prof"
    names = {fn for (_file, _line, fn) in pstats.Stats(str(path)).stats}
    assert "_work" in names
    assert profiling.dump() is None  # already written


def test_nothing_without_the_variable(tmp_path, monkeypatch):
    monkeypatch.delenv(profiling.ENV_PROFILE_DIR, raising=False)
    assert not profiling.start("clock")
    assert profiling.dump() is None
    assert list(tmp_path.iterdir()) == []
