"""Local-run store batches (bringup/engine/store_batches.py): same final rows as per-step commits, the file
always at a commit (a step boundary), a failed run's open batch dropped, a batch never lost at close.

Oracle: the same scripted writes applied through per-step commits (what a ROS satellite does) on a
second store; a second SQLite connection reads what the file holds between commits.
"""

import random

import pytest

from bringup.engine.store_batches import StoreBatches
from sat_node.dtn.store import BundleStore, StoredBundle


def _rows(path) -> list[tuple]:
    other = BundleStore(path)
    try:
        return [tuple(b) for b in other.load_all()]
    finally:
        other.close()


def _script(seed: int, steps: int):
    """Per step: a list of ('put', bundle) / ('del', id) / ('meta', key, value) writes."""
    rng = random.Random(seed)
    live: list[str] = []
    out = []
    n = 0
    for k in range(steps):
        ops = []
        for _ in range(rng.randint(0, 6)):
            r = rng.random()
            if r < 0.55 or not live:
                bid = f"ipn:1.{n}"
                n += 1
                live.append(bid)
                ops.append(("put", StoredBundle(bid, bytes([n % 256]) * 8, rng.randint(1, 15), "sat_12",
                                                k * 10**10 + 900 * 10**9, k * 10**10)))
            elif r < 0.9:
                ops.append(("del", live.pop(rng.randrange(len(live)))))
            else:
                ops.append(("meta", "seq", n))
        out.append(ops)
    return out


def _apply(store: BundleStore, ops) -> None:
    """One satellite step: the satellite's own per-step begin/commit around its writes."""
    own = store.begin()
    for op in ops:
        if op[0] == "put":
            store.put(op[1])
        elif op[0] == "del":
            store.delete(op[1])
        else:
            store.set_meta(op[1], op[2])
    if own:
        store.commit()


@pytest.mark.parametrize("every", [1, 7, 50])
def test_batches_leave_the_rows_of_per_step_commits(tmp_path, every):
    script = _script(every, 120)
    ref = BundleStore(tmp_path / "ref.sqlite")
    for ops in script:
        _apply(ref, ops)
    ref.close()

    st = BundleStore(tmp_path / "b.sqlite")
    batches = StoreBatches([st], every_steps=every)
    batches.start()
    for ops in script:
        batches.step()
        _apply(st, ops)
    batches.finish()
    assert batches.commits == (120 - 1) // every + 1  # before steps every, 2*every, ... and at the end
    assert st.get_meta("seq") == BundleStore(tmp_path / "ref.sqlite").get_meta("seq")
    st.close()
    assert _rows(tmp_path / "b.sqlite") == _rows(tmp_path / "ref.sqlite")
    assert len(_rows(tmp_path / "ref.sqlite")) > 10


def test_file_between_commits_is_the_last_commit(tmp_path):
    script = _script(3, 40)
    st = BundleStore(tmp_path / "b.sqlite")
    batches = StoreBatches([st], every_steps=10)
    batches.start()
    ref = BundleStore(tmp_path / "ref.sqlite")
    snapshots = {}
    for k, ops in enumerate(script):
        batches.step()  # before step k: commits steps k-10..k-1 when k is a multiple of 10
        if k % 10 == 0 and k:
            snapshots[k] = _rows(tmp_path / "ref.sqlite")
        _apply(ref, ops)
        _apply(st, ops)
        if k in (5, 15, 25):  # mid-batch: the file shows the state after step (k // 10) * 10 - 1
            assert _rows(tmp_path / "b.sqlite") == (snapshots[k - 5] if k > 5 else [])
    batches.finish()


def test_abandon_keeps_the_last_commit_and_a_failed_step_adds_nothing(tmp_path):
    script = _script(5, 30)
    st = BundleStore(tmp_path / "b.sqlite")
    batches = StoreBatches([st], every_steps=10)
    batches.start()
    for k, ops in enumerate(script):
        batches.step()
        if k == 20:
            committed = _rows(tmp_path / "b.sqlite")
        _apply(st, ops)
    len(st)  # a read flushes the batch into the open transaction: abandon must roll that back too
    batches.abandon()
    assert _rows(tmp_path / "b.sqlite") == committed
    # the store is usable again and outside a batch writes autocommit
    st.put(StoredBundle("ipn:9.1", b"x", 1, "sat_12", 1, 0))
    assert ("ipn:9.1", b"x", 1, "sat_12", 1, 0) in _rows(tmp_path / "b.sqlite")


def test_start_refuses_a_store_with_an_open_transaction(tmp_path):
    st = BundleStore(tmp_path / "b.sqlite")
    assert st.begin()
    with pytest.raises(RuntimeError, match="already open"):
        StoreBatches([st]).start()
    with pytest.raises(ValueError, match="every_steps"):
        StoreBatches([st], every_steps=0)


def test_a_local_run_batches_every_satellite_store_and_ends_with_per_step_rows(tmp_path, monkeypatch):
    """Through `constellation run --engine local`: every satellite's store is in the batches (an empty
    store is falsy - len 0 - and must not be left out) and the files end as with per-step commits."""
    import bringup.engine.store_batches as sb
    from bringup.cli.main import main

    seen = []
    start = sb.StoreBatches.start

    def spy(self):
        seen.append((len(self.stores), self.every_steps))
        start(self)

    monkeypatch.setattr(sb.StoreBatches, "start", spy)
    args = ["run", "--engine", "local", "--mode", "distributed", "--sats", "24", "--hours", "2",
            "--no-plots", "--no-progress"]
    assert main([*args, "--out", str(tmp_path / "batched")]) == 0
    monkeypatch.setattr(sb.StoreBatches.__init__, "__defaults__", (1,))
    assert main([*args, "--out", str(tmp_path / "per_step")]) == 0
    assert seen[0] == (24, sb.STORE_COMMIT_STEPS) and seen[-1] == (24, 1)
    files = sorted((tmp_path / "per_step" / "store").glob("*.sqlite"))
    assert len(files) == 24
    for f in files:  # (the paper run's satellites hold no bundle at the end: rows are [] here)
        assert _rows(tmp_path / "batched" / "store" / f.name) == _rows(f)
    meta = [BundleStore(f).get_meta("seq", -1) for f in files]  # bundles each satellite created
    assert sum(m > 0 for m in meta) >= 10
    assert meta == [BundleStore(tmp_path / "batched" / "store" / f.name).get_meta("seq", -1) for f in files]
