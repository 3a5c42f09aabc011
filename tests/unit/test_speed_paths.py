"""The fast paths of issue 5 (speed) give exactly what the plain paths give.

Oracles: rosbags' own Writer.write (the bag file must be byte-identical with and without
bringup/recording.py's _fast_write), a brute-force settle (every in-flight transmission checked),
and SQLite's own transaction state for the per-step store transaction.
"""

from __future__ import annotations

import random

from bringup.recording import BagReader, BagWriter
from msgs_json.envelope import Envelope


def _write(path, fast_off: bool) -> None:
    rng = random.Random(7)
    with BagWriter(path, fast_off=fast_off) as bag:
        t = 0
        for i in range(30000):  # > 1 MiB: several chunks
            t += rng.randrange(0, 10**9)
            topic = f"/sat_{rng.randrange(1, 9):02d}/dtn/in"
            data = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 80))) if i % 3 else f"m{i}"
            bag.write_envelope(Envelope(t, "x", i, topic, data))
            if i % 50 == 0:
                bag.write_clock(t)


def test_fast_bag_write_is_byte_identical(tmp_path):
    _write(tmp_path / "fast" / "bag", False)  # same bag name: the summary names its file
    _write(tmp_path / "slow" / "bag", True)
    a = (tmp_path / "fast" / "bag" / "bag.mcap").read_bytes()
    b = (tmp_path / "slow" / "bag" / "bag.mcap").read_bytes()
    assert len(a) > 2**20 and a == b
    ya = (tmp_path / "fast" / "bag" / "metadata.yaml").read_text()
    yb = (tmp_path / "slow" / "bag" / "metadata.yaml").read_text()
    assert ya == yb
    with BagReader(tmp_path / "fast" / "bag") as r:
        envs = list(r.envelopes())
    assert len(envs) == 30000 and envs[5].seq == 5


def test_settle_prefix_equals_brute_force():
    from sat_node.dtn.agent import AgentConfig, BundleAgent
    from orbit_clock.contact_plan import Contact, ContactPlan

    plan = ContactPlan([Contact(0.0, 1e4, "sat_11", "sat_12", 1e4, 0.01),
                        Contact(0.0, 1e4, "sat_12", "sat_11", 1e4, 0.01)])
    ag = BundleAgent("sat_11", plan, AgentConfig(settle_delay_s=0.5))
    txs = []
    for k in range(20):
        ag.originate(b"x" * 10, "sat_12", 1 + k % 3, k * 10**8)
        txs += ag.transmissions_until(k * 10**8)
    assert len(txs) >= 5
    ends = [tx.end_ns for tx in txs]
    assert ends == sorted(ends)  # the invariant the prefix scan relies on
    for now in range(0, 4 * 10**9, 10**8):
        expect = {b for b, (tx, _h) in ag._in_flight.items() if tx.end_ns + 5 * 10**8 > now}
        ag._settle(now)
        assert set(ag._in_flight) == expect


def test_store_step_transaction(tmp_path):
    from sat_node.dtn.store import BundleStore, StoredBundle

    st = BundleStore(tmp_path / "s.sqlite")
    assert st.begin() is True and not st.in_transaction  # BEGIN waits for the first write
    assert st.begin() is False  # nested: the outer opener commits
    st.put(StoredBundle("a", b"1", 1, "sat_12", 5, 0))
    st.delete("zz")
    assert st.in_transaction
    st.commit()
    assert not st.in_transaction
    other = BundleStore(tmp_path / "s.sqlite")
    assert [b.bundle_id for b in other.load_all()] == ["a"]


def test_crc16_x25_fast_equals_table():
    import os

    from sat_node.dtn.bpv7 import _crc16_x25_table, crc16_x25

    assert crc16_x25(b"123456789") == 0x906E  # the catalogue's check value for CRC-16/X-25
    for n in range(0, 300, 7):
        d = os.urandom(n)
        assert crc16_x25(d) == _crc16_x25_table(d)


def test_bundle_encode_cache_follows_fields():
    from sat_node.dtn.bpv7 import Bundle, decode_bundle, encode_bundle

    b = Bundle(dest=(12, 1), src=(11, 1), creation_ms=10**9, seq=3, lifetime_ms=900_000, payload=b"abc")
    e1 = encode_bundle(b)
    assert encode_bundle(b) == e1 and decode_bundle(e1).payload == b"abc"
    b.payload = b"abcd"
    b.lifetime_ms = 1000
    e2 = encode_bundle(b)
    fresh = Bundle(dest=(12, 1), src=(11, 1), creation_ms=10**9, seq=3, lifetime_ms=1000, payload=b"abcd")
    assert e2 == encode_bundle(fresh) != e1


def test_fast_chunk_reader_yields_what_rosbags_yields(tmp_path):
    import rosbags.rosbag2.storage_mcap as sm

    _write(tmp_path / "bag", False)  # several chunks, random (and tied) log times
    with BagReader(tmp_path / "bag") as r:
        fast = list(r.messages())
    fast_fn = sm.msgsrc
    try:
        sm.msgsrc = sm._msgsrc_orig
        with BagReader(tmp_path / "bag") as r:
            slow = list(r.messages())
    finally:
        sm.msgsrc = fast_fn
    assert fast_fn is not sm._msgsrc_orig
    assert len(fast) == 30600 and fast == slow
