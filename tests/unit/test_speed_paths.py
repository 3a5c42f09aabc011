"""The fast paths give exactly what the plain paths give.

Oracles: rosbags' own Writer.write, chunk close and QoS YAML (the bag file must be byte-identical
with and without bringup/recording/bag.py's _fast_write and bringup/recording/rosbags_speedups.py,
the bag summary dumped by libyaml in both), rosbags' own summary dump (ruamel: metadata.yaml and the
MCAP's rosbag2 record load to the same mapping, the file is rosbags' byte for byte up to that
record, rosbags' Reader and the mcap reader open both bags alike), rosbags' own chunk reader and QoS
parse (same messages, same QoS),  a brute-force settle (every in-flight transmission checked),
SQLite's own transaction state for the per-step store transaction, and the DP kernel walking each
path for its path tables.
"""

from __future__ import annotations

import random
import subprocess
import sys
from contextlib import nullcontext

from bringup.recording import rosbags_speedups
from bringup.recording.bag import BagReader, BagWriter
from msgs_json.envelope import Envelope
from tests.keys import TEST_BPSEC_KEY


def _write(path, fast_off: bool, close_in=nullcontext) -> None:
    """30000 envelopes and 600 clocks; the bag closed inside ``close_in()``."""
    rng = random.Random(7)
    bag = BagWriter(path, fast_off=fast_off)
    t = 0
    for i in range(30000):  # > 1 MiB: several chunks
        t += rng.randrange(0, 10**9)
        topic = f"/sat_{rng.randrange(1, 9):02d}/dtn/in"
        data = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 80))) if i % 3 else f"m{i}"
        bag.write_envelope(Envelope(t, "x", i, topic, data))
        if i % 50 == 0:
            bag.write_clock(t)
    with close_in():
        bag.close()


def _write_batched(path, sizes) -> None:
    """The envelopes of _write through write_envelopes, in batches of the given sizes (cycled);
    the clocks in between as _write writes them."""
    rng = random.Random(7)
    envs, clocks = [], []
    t = 0
    for i in range(30000):
        t += rng.randrange(0, 10**9)
        topic = f"/sat_{rng.randrange(1, 9):02d}/dtn/in"
        data = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 80))) if i % 3 else f"m{i}"
        envs.append(Envelope(t, "x", i, topic, data))
        clocks.append(t if i % 50 == 0 else None)
    with BagWriter(path) as bag:
        i = k = 0
        while i < len(envs):
            n = min(sizes[k % len(sizes)], len(envs) - i)
            k += 1
            for j in range(i, min(i + n, len(envs))):  # clock of envelope j goes after it: split there
                if clocks[j] is not None:
                    n = j + 1 - i
                    break
            bag.write_envelopes(envs[i:i + n])
            if clocks[i + n - 1] is not None:
                bag.write_clock(clocks[i + n - 1])
            i += n


def _slow_bag(path, summary: str = "libyaml") -> None:
    """_write through rosbags' own Writer.write, McapWriter.close_chunk and QoS dump (no fast path);
    the bag summary (metadata.yaml, the MCAP's rosbag2 record) dumped by libyaml as the fast path
    dumps it (``summary="libyaml"``: rosbags' Writer.close inside rosbags_speedups.metadata_yaml)
    or by rosbags' own ruamel.yaml (``"ruamel"``)."""
    rosbags_speedups.install()
    _write(path, True, rosbags_speedups.metadata_yaml if summary == "libyaml" else nullcontext)


def test_fast_bag_write_is_byte_identical(tmp_path):
    _write(tmp_path / "fast" / "bag", False)  # same bag name: the summary names its file
    _slow_bag(tmp_path / "slow" / "bag")
    a = (tmp_path / "fast" / "bag" / "bag.mcap").read_bytes()
    b = (tmp_path / "slow" / "bag" / "bag.mcap").read_bytes()
    assert len(a) > 2**20 and a == b
    ya = (tmp_path / "fast" / "bag" / "metadata.yaml").read_text()
    yb = (tmp_path / "slow" / "bag" / "metadata.yaml").read_text()
    assert ya == yb
    with BagReader(tmp_path / "fast" / "bag") as r:
        envs = list(r.envelopes())
    assert len(envs) == 30000 and envs[5].seq == 5


def test_fast_summary_is_rosbags_summary_parse_equal(tmp_path):
    """The fast path's bag summary is libyaml's text, not ruamel's (rosbags_speedups.metadata_yaml):
    metadata.yaml and the MCAP's rosbag2 Metadata record load to rosbags' own mapping in every
    reader, the .mcap is rosbags' byte for byte up to that record and its summary section lists the
    same schemas, channels, statistics and chunks, and rosbags' Reader (on the folder: metadata.yaml
    through ruamel; on the file) and the mcap reader open both bags alike."""
    import yaml
    from mcap.reader import make_reader
    from rosbags.rosbag2 import Reader
    from ruamel.yaml import YAML

    from bringup.recording import metadata_yaml

    _write(tmp_path / "fast" / "bag", False)
    _slow_bag(tmp_path / "slow" / "bag", summary="ruamel")
    fast, slow = tmp_path / "fast" / "bag", tmp_path / "slow" / "bag"
    ya, yb = (fast / "metadata.yaml").read_text(), (slow / "metadata.yaml").read_text()
    assert ya != yb and "type_description_hash: \n" in yb  # ruamel folds the long hashes, libyaml does not
    loaders = [YAML(typ="safe").load, lambda t: yaml.load(t, Loader=yaml.SafeLoader), metadata_yaml.load]
    for load in loaders:
        assert load(ya) == load(yb)
    info = YAML(typ="safe").load(yb)["rosbag2_bagfile_information"]
    assert info["message_count"] == 30600 and len(info["topics_with_message_count"]) == 9

    a, b = (fast / "bag.mcap").read_bytes(), (slow / "bag.mcap").read_bytes()
    with open(fast / "bag.mcap", "rb") as fa, open(slow / "bag.mcap", "rb") as fb:
        ra, rb = make_reader(fa, validate_crcs=True), make_reader(fb, validate_crcs=True)
        sa, sb = ra.get_summary(), rb.get_summary()
        for part in ("schemas", "channels", "statistics", "chunk_indexes"):
            assert getattr(sa, part) == getattr(sb, part), part
        (ia,), (ib,) = [m for m in sa.metadata_indexes if m.name == "rosbag2"], [m for m in sb.metadata_indexes
                                                                                if m.name == "rosbag2"]
        assert ia.offset == ib.offset and a[:ia.offset] == b[:ib.offset]  # rosbags' bytes up to the record
        ma, mb = ({m.name: m.metadata for m in r.iter_metadata()} for r in (ra, rb))
        assert ma.keys() == mb.keys() == {"rosbag2"}  # (the leading constellation record is in the bytes above)
        sma, smb = ma["rosbag2"]["serialized_metadata"], mb["rosbag2"]["serialized_metadata"]
        assert sma != smb
        for load in loaders:
            assert load(sma) == load(smb) == load(yb)["rosbag2_bagfile_information"]
        got = [[(ch.topic, m.log_time, m.data) for _s, ch, m in r.iter_messages()] for r in (ra, rb)]
        assert len(got[0]) == 30600 and got[0] == got[1]

    def opened(where):
        with Reader(where) as r:
            return ((r.duration, r.start_time, r.end_time, r.message_count, r.compression_format,
                     r.compression_mode, r.ros_distro, r.storage.metadata.custom),
                    [(c.id, c.topic, c.msgtype, c.msgcount, c.digest, c.msgdef, c.ext) for c in r.connections],
                    [(c.id, t, bytes(raw)) for c, t, raw in r.messages()])

    for where in ("", "bag.mcap"):
        x, y = opened(fast / where), opened(slow / where)
        assert x == y and len(x[2]) == 30600 and all(c[6].offered_qos_profiles for c in x[1])
    with BagReader(fast) as r, BagReader(fast, fast=False) as s:
        assert r.warnings == s.warnings == [] and r.offered_qos() == s.offered_qos()


def test_settle_prefix_equals_brute_force():
    from sat_node.dtn.agent import AgentConfig, BundleAgent
    from orbit_clock.contact_plan import Contact, ContactPlan

    plan = ContactPlan([Contact(0.0, 1e4, "sat_11", "sat_12", 1e4, 0.01),
                        Contact(0.0, 1e4, "sat_12", "sat_11", 1e4, 0.01)])
    ag = BundleAgent("sat_11", plan, AgentConfig(key=TEST_BPSEC_KEY, settle_delay_s=0.5))
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
    _write(tmp_path / "bag", False)  # several chunks, random (and tied) log times
    with BagReader(tmp_path / "bag") as r:
        fast = list(r.messages())
    with BagReader(tmp_path / "bag", fast=False) as r:
        slow = list(r.messages())
    assert len(fast) == 30600 and fast == slow


def _random_bundles(n: int, seed: int):
    """Bundles of every shape decode_bundle meets: the agent's (priority, hop count, BIB, previous node,
    next hop) and others (CRC-32C or no CRC, fragments, CRCs on blocks, unknown blocks, bundle age,
    creation time 0, report-to, dtn:none)."""
    from sat_node.dtn.bpsec import add_bib
    from sat_node.dtn.bpv7 import CRC_16, CRC_32C, CRC_NONE, Bundle, CanonicalBlock, Imc
    from sat_node.dtn.routing_blocks import set_routing

    rng = random.Random(seed)
    out = []
    for i in range(n):
        b = Bundle(dest=rng.choice([(rng.randrange(0, 40), rng.choice([0, 1])), Imc(1, rng.choice([0, 1]))]),
                   src=(rng.randrange(1, 40), 1),
                   creation_ms=rng.choice([0, rng.randrange(1, 2**40)]), seq=rng.randrange(0, 300),
                   lifetime_ms=rng.randrange(0, 10**7), payload=bytes(rng.randrange(256) for _ in range(rng.randrange(0, 90))),
                   crc_type=rng.choice([CRC_16, CRC_16, CRC_32C, CRC_NONE]),
                   report_to=rng.choice([None, None, (0, 0), (7, 2)]))
        if rng.random() < 0.1:
            b.flags, b.fragment = 1, (rng.randrange(0, 50), rng.randrange(50, 500))
        if b.creation_ms == 0 or rng.random() < 0.2:
            b.age_ms = rng.randrange(0, 10**6)
        if rng.random() < 0.8:
            set_routing(b, [(b.dest[0], rng.randrange(1, 16), b.lifetime_ms)],
                        {rng.randrange(0, 40): (b.dest[0],)} if rng.random() < 0.8 else None)
            b.hop_count = (32, rng.randrange(0, 5))
            add_bib(b, b"k" * 32, (b.src[0], 0))
        if rng.random() < 0.7:
            b.previous_node = (rng.randrange(0, 40), 0)
        if rng.random() < 0.15:
            b.blocks.append(CanonicalBlock(200 + i % 3, 40 + i % 5, i % 2, rng.choice([CRC_NONE, CRC_16, CRC_32C]), b"\x01\x02"))
        if rng.random() < 0.1:
            b.payload_crc_type = CRC_32C
        out.append(b)
    return out


def _decode_outcome(fn, data):
    from sat_node.dtn.bpv7 import BundleError

    try:
        b = fn(data)
    except BundleError as exc:
        return ("error", str(exc))
    # repr tells 1 from True; primary_raw is not part of Bundle equality
    return ("ok", repr(b), b.primary_raw)


def test_fast_decode_equals_plain_decode_on_random_bundles_and_corruptions():
    from sat_node.dtn import bpv7

    rng = random.Random(3)
    n_fast = 0
    for b in _random_bundles(300, 11):
        raw = bpv7.encode_bundle(b)
        want = _decode_outcome(bpv7._decode_plain, raw)
        assert want[0] == "ok"
        assert _decode_outcome(bpv7.decode_bundle, raw) == want
        n_fast += bpv7._decode_fast(raw) is not None
        for _ in range(12):  # corruptions: the fast path must never accept what the plain one rejects
            bad = bytearray(raw)
            i = rng.randrange(len(bad))
            bad[i] ^= rng.choice([1, 2, 0x20, 0x80, 0xFF])
            bad = bytes(bad)
            assert _decode_outcome(bpv7.decode_bundle, bad) == _decode_outcome(bpv7._decode_plain, bad), (raw.hex(), i)
    assert n_fast > 100  # the fast path is really taken on the common shape


def test_remembered_sent_bytes_decode_as_parsed_ones():
    """decode_bundle of bytes a sender noted (remember_sent) returns what parsing them returns (fields,
    blocks, primary block bytes), on random bundles of every shape - the uncommon ones are not noted
    - and a fresh Bundle each time (a receiver changes its copy); remember_unicast_peek notes what
    the medium's peek parses."""
    from sat_node.dtn import bpv7, routing_blocks
    from sat_node.dtn.routing_blocks import set_routing

    noted = peeks = 0
    for k, b in enumerate(_random_bundles(400, 17)):
        if k % 3 == 0 and b.block(routing_blocks.RECIPIENTS_BLOCK) is not None:
            split = {11 + k % 20: (b.dest[0],)}
            set_routing(b, [(b.dest[0], 1 + k % 15, b.lifetime_ms)], split)
        else:
            split = None
        raw = bpv7.encode_bundle(b)
        want = _decode_outcome(bpv7._decode_plain, raw)
        bpv7._SENT.clear()
        bpv7.remember_sent(raw, b)
        if raw in bpv7._SENT:
            noted += 1
            assert want[0] == "ok"
        got = bpv7.decode_bundle(raw)
        assert _decode_outcome(bpv7.decode_bundle, raw) == want
        again = bpv7.decode_bundle(raw)
        assert again is not got and again.blocks is not got.blocks and again._enc is not got._enc
        if split is not None:
            routing_blocks._PEEK.clear()
            try:
                parsed = routing_blocks._peek(raw)
            except bpv7.BundleError:  # e.g. a routing block twice: never noted
                parsed = None
            routing_blocks._PEEK.clear()
            routing_blocks.remember_unicast_peek(raw, b, split)
            assert routing_blocks._PEEK.get(raw, parsed) == parsed
            peeks += raw in routing_blocks._PEEK
    bpv7._SENT.clear()
    routing_blocks._PEEK.clear()
    assert noted > 60 and peeks > 20  # the common shape is noted (the others: creation time 0, fragments...)


def test_memoised_routing_encoders_equal_fresh_encodings():
    """encode_recipients / encode_next_hops from their memo give the bytes a fresh encoding gives,
    whatever the order or the int-like types of the input (and lists, unhashable, still encode)."""
    import cbor2

    from sat_node.dtn import routing_blocks as rb

    rng = random.Random(5)
    for _ in range(600):
        rcpts = [(rng.randrange(11, 40), rng.randrange(1, 16), rng.choice([900000, 1800000, 3000000]))
                 for _ in range(rng.randrange(1, 4))]
        split = {rng.randrange(11, 40): tuple(r[0] for r in rcpts[: rng.randrange(1, len(rcpts) + 1)])}
        want_r = cbor2.dumps([x for r in sorted(rcpts) for x in r])
        want_s = cbor2.dumps([x for nh in sorted(split) for x in (nh, sorted(split[nh]))])
        for form in (rcpts, tuple(reversed(rcpts)), [list(r) for r in rcpts], [(True if r[0] == 1 else r[0], *r[1:])
                                                                            for r in rcpts]):
            assert rb.encode_recipients(form) == want_r
        assert rb.encode_next_hops(split) == want_s
        assert rb.encode_next_hops({k: list(v) for k, v in split.items()}) == want_s
    assert rb._ENC_RCPT and rb._ENC_SPLIT


def test_block_and_primary_encodings_from_caches_equal_fresh_ones():
    import cbor2

    from sat_node.dtn import bpv7

    for b in _random_bundles(100, 5):
        raw = bpv7.encode_bundle(b)
        items = cbor2.loads(raw)
        assert raw[1:1 + len(cbor2.dumps(items[0]))] == cbor2.dumps(items[0])
        fresh = bpv7.Bundle(**{f: getattr(b, f) for f in ("dest", "src", "creation_ms", "seq", "lifetime_ms",
                                                           "payload", "report_to", "flags", "crc_type", "fragment",
                                                           "payload_crc_type", "payload_flags")})
        fresh.blocks = [bpv7.CanonicalBlock(x.type, x.number, x.flags, x.crc_type, x.data) for x in b.blocks]
        bpv7._BLOCK_RAW.clear()
        bpv7._PRIM_RAW.clear()
        assert bpv7.encode_bundle(fresh) == raw


def test_bib_verify_with_parse_cache_still_rejects():
    import pytest

    from sat_node.dtn.bpsec import IntegrityError, add_bib, verify_bib
    from sat_node.dtn.bpv7 import decode_bundle, encode_bundle

    for b in _random_bundles(40, 9):
        if b.block(11) is None:
            add_bib(b, b"k" * 32, (b.src[0], 0))
        raw = encode_bundle(b)
        verify_bib(decode_bundle(raw), b"k" * 32)  # parse cached now
        with pytest.raises(IntegrityError):
            verify_bib(decode_bundle(raw), b"x" * 32)
        c = decode_bundle(raw)
        c.payload = c.payload + b"!"
        with pytest.raises(IntegrityError):
            verify_bib(c, b"k" * 32)


def test_bib_caches_filled_when_made_equal_parse_and_check():
    """What add_bib leaves in verify_bib's caches (the BIB's parse, its MACs as checked) is what
    parsing its bytes gives and what a fresh check says (also for other variants and scopes); a
    changed payload, primary block or key is still checked, and fails."""
    import dataclasses

    import pytest

    from sat_node.dtn import bpsec
    from sat_node.dtn.bpv7 import decode_bundle, encode_bundle

    rng = random.Random(21)
    made = 0
    for b in _random_bundles(120, 23):
        bpsec._ASB.clear()
        bpsec._VERIFIED.clear()
        variant, scope = rng.choice([(6, 7), (6, 7), (5, 1), (7, 6), (6, 0)])
        bpsec.add_bib(b, b"k" * 32, (b.src[0], 0), sha_variant=variant, scope=scope)
        blk = b.block(11)
        if blk.data in bpsec._ASB:
            made += 1
            assert bpsec._ASB[blk.data] == bpsec._parse_asb_plain(blk.data)
            assert len(bpsec._VERIFIED) == 1
        raw = encode_bundle(b)
        remembered = set(bpsec._VERIFIED)
        bpsec._VERIFIED.clear()
        bpsec.verify_bib(decode_bundle(raw), b"k" * 32)  # a fresh check: passes, and notes the same inputs
        assert remembered <= bpsec._VERIFIED
        bpsec._VERIFIED |= remembered
        with pytest.raises(bpsec.IntegrityError):
            bpsec.verify_bib(decode_bundle(raw), b"x" * 32)
        c = decode_bundle(raw)
        c.payload = c.payload + b"!"
        with pytest.raises(bpsec.IntegrityError):
            bpsec.verify_bib(c, b"k" * 32)
        if scope & 1:
            c = dataclasses.replace(decode_bundle(raw), seq=b.seq + 1, primary_raw=None)
            with pytest.raises(bpsec.IntegrityError):
                bpsec.verify_bib(c, b"k" * 32)
    assert made > 100


def test_open_contacts_window_equals_full_scan():
    from dtn_router.link import LinkModel
    from orbit_clock.contact_plan import Contact, ContactPlan

    rng = random.Random(4)
    cs = []
    for _ in range(400):
        s = rng.uniform(0, 20000)
        a, b = rng.sample(["sat_11", "sat_12", "sat_13", "sat_14"], 2)
        cs.append(Contact(s, s + rng.choice([1.0, rng.uniform(1, 3000), rng.uniform(3000, 21600), 3600.0]),
                          a, b, 1e4, 0.01))
    lm = LinkModel(ContactPlan(cs))
    for _ in range(3000):
        t = rng.choice([rng.uniform(-10, 24000), rng.choice(cs).start_s, rng.choice(cs).end_s])
        sender = rng.choice(["sat_11", "sat_12", "sat_13", "sat_14", "sat_99"])
        full = [c for c in lm._by_src.get(sender, []) if c.start_s <= t and c.end_s > t]
        assert lm.open_contacts(sender, t) == full
    # the memo transmit reads: mostly increasing times per sender (a radio's), with steps back
    for sender in ["sat_11", "sat_12", "sat_99"]:
        t = -5.0
        hits = 0
        for _ in range(3000):
            t = t + rng.choice([0.0, 0.5, 2.0, 40.0, 300.0]) if rng.random() < 0.95 else rng.uniform(-10, 24000)
            memo = lm._open_memo.get(sender)
            hits += memo is not None and memo[0] <= t < memo[1]
            assert lm._open_at(sender, t) == [c for c in lm._by_src.get(sender, []) if c.start_s <= t < c.end_s]
        assert hits > 100


def test_transmit_from_the_open_set_view_equals_the_contact_scan():
    """dtn_router/link.py: transmit reading each receiver's longest open contact and the sorted copy
    template (_view, made once per open set) gives every outcome of the contact-by-contact scan it
    replaced (kept below as the oracle): on drawn plans with one contact per receiver, with two
    overlapping contacts to one receiver (the scan path), equal end times, equal light times
    (ties broken by node), contacts ending mid-transmission, multicast next hops, a busy radio."""
    from dtn_router.link import _NS, Copy, LinkModel, LinkOutcome
    from orbit_clock.contact_plan import Contact, ContactPlan

    class Scan(LinkModel):
        def transmit(self, sender, next_hop, start_ns, bits):
            self.counters["tx"] += 1
            hops = (next_hop,) if isinstance(next_hop, str) else tuple(next_hop)
            if start_ns < self._busy_until_ns.get(sender, -1):
                self.counters["radio_busy"] += 1
                return LinkOutcome(False, start_ns, [], "radio_busy", {h: "radio_busy" for h in hops})
            open_now = self._open_at(sender, start_ns / _NS)
            links = {}
            for h in hops:
                mine = [c for c in open_now if c.dst == h]
                if mine:
                    links[h] = max(mine, key=lambda c: c.end_s)
            if not links:
                self.counters["no_contact"] += 1
                return LinkOutcome(False, start_ns, [], "no_contact", {h: "no_contact" for h in hops})
            rate = min(c.rate_bps for c in links.values())
            end_ns = start_ns + int(-(-bits * _NS // int(rate))) if float(rate).is_integer() \
                else start_ns + int(bits / rate * _NS + 0.999999)
            self._busy_until_ns[sender] = end_ns
            self.air_ns[sender] = self.air_ns.get(sender, 0) + end_ns - start_ns
            self.bits_sent[sender] = self.bits_sent.get(sender, 0) + int(bits)
            failed = {h: ("no_contact" if h not in links else "contact_ended") for h in hops
                      if h not in links or end_ns > links[h].end_s * _NS}
            copies, seen = [], set()
            for c in open_now:
                if c.dst in seen or c.end_s * _NS < end_ns:
                    continue
                seen.add(c.dst)
                copies.append(Copy(c.dst, end_ns + round(c.range_light_s * _NS)))
            copies.sort(key=lambda x: (x.arrival_ns, x.node))
            self.counters["copies"] += len(copies)
            if failed:
                for reason in failed.values():
                    self.counters[reason] += 1
                copies = [x for x in copies if x.node not in failed]
                return LinkOutcome(False, end_ns, copies, next(iter(failed.values())), failed)
            self.counters["ok"] += 1
            return LinkOutcome(True, end_ns, copies, "")

    nodes = [f"sat_{k}" for k in range(11, 23)]
    for seed, doubles in ((1, False), (2, True), (3, True)):
        rng = random.Random(seed)
        cs = []
        for a in nodes:
            for b in nodes:
                if a == b:
                    continue
                s = 0.0
                while s < 2000:
                    s += rng.choice([0.0, 1.0, rng.uniform(0, 30)])
                    e = s + rng.choice([0.2, 5.0, 60.0, 300.0, rng.uniform(0, 900)])
                    cs.append(Contact(round(s, 3), round(e, 3), a, b, rng.choice([1e4, 2.5e3, 1234.5]),
                                      rng.choice([0.01, 0.02, rng.uniform(0, 0.02)])))
                    if doubles and rng.random() < 0.2:  # an overlapping second contact to the same receiver
                        cs.append(Contact(round(s + 0.1, 3), round(e + rng.choice([0.0, 3.0, -0.05]), 3), a, b,
                                          1e4, 0.015))
                    s = e
        new, old = LinkModel(ContactPlan(cs)), Scan(ContactPlan(cs))
        t = {n: 0 for n in nodes}
        n_copies = n_scan_path = 0
        for _ in range(4000):
            sender = rng.choice(nodes)
            t[sender] += rng.choice([0, 10**8, 10**9, 2 * 10**9, 5 * 10**9, 3 * 10**10])
            hops = rng.choice([rng.choice(nodes), tuple(rng.sample(nodes, 3)), "sat_99"])
            bits = rng.choice([2000, 2000, 2000, 40000])
            if rng.random() < 0.2:  # a transmission ending exactly as a contact of its sender closes
                c = rng.choice([c for c in cs if c.src == sender and c.rate_bps == 1e4])
                bits, t[sender] = 2000, max(t[sender], round(c.end_s * _NS) - 2 * 10**8)
                hops = c.dst
            a, b = new.transmit(sender, hops, t[sender], bits), old.transmit(sender, hops, t[sender], bits)
            assert a == b
            n_copies += len(a.copies)
            n_scan_path += new._view_memo[sender][2] is None if sender in new._view_memo else 0
        assert new.counters == old.counters and new.air_ns == old.air_ns and new.bits_sent == old.bits_sent
        assert n_copies > 1000 and min(new.counters[k] for k in ("ok", "no_contact", "contact_ended", "radio_busy")) > 0
        assert (n_scan_path > 100) == doubles


def test_memoised_qos_parse_equals_rosbags_parse(tmp_path):
    _write(tmp_path / "bag", False)
    with BagReader(tmp_path / "bag") as r:
        fast = [(c.topic, c.ext.offered_qos_profiles) for c in r._r.connections]
    with BagReader(tmp_path / "bag", fast=False) as r:
        slow = [(c.topic, c.ext.offered_qos_profiles) for c in r._r.connections]
    assert len(fast) >= 8 and fast == slow and any(q for _t, q in fast)


def test_speedups_stay_inside_the_projects_bags(tmp_path):
    """Importing the recording changes nothing in rosbags; after a BagWriter and a BagReader, the
    McapWriter class keeps rosbags' chunk close and rosbags' functions run rosbags' own code outside
    the bag's calls (the fast versions' memo tables do not grow)."""
    code = ("import rosbags.rosbag2.storage_mcap as sm, rosbags.rosbag2.writer as w, rosbags.rosbag2.metadata as md\n"
            "import rosbags.rosbag2.reader as rd\n"
            "before = (sm.msgsrc, sm.parse_qos, w.dump_qos_v9, md.parse_qos, sm.McapWriter.close_chunk, w.YAML, rd.YAML)\n"
            "import bringup.recording.bag, bringup.analysis.report, bringup.cli.main\n"
            "assert before == (sm.msgsrc, sm.parse_qos, w.dump_qos_v9, md.parse_qos, sm.McapWriter.close_chunk,"
            " w.YAML, rd.YAML)\n")
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)

    from rosbags.rosbag2 import Reader, Writer
    from rosbags.rosbag2.storage_mcap import McapWriter

    from bringup.recording import rosbags_speedups as su
    from bringup.recording.bag import TYPESTORE, make_qos

    _write(tmp_path / "ours", False)
    with BagReader(tmp_path / "ours") as r:
        assert len(list(r.messages())) == 30600
    assert not hasattr(McapWriter.close_chunk, "rosbags_original") and McapWriter.close_chunk.__module__.startswith("rosbags")
    n_dumps, n_parsed = len(su._QOS_DUMPS), len(su._QOS_PARSED)
    w = Writer(tmp_path / "theirs", version=9)
    w.open()
    c = w.add_connection("/x", "std_msgs/msg/String", typestore=TYPESTORE,
                         offered_qos_profiles=[make_qos(depth=17)])  # a profile our bags never use
    w.write(c, 5, bytes([0, 1, 0, 0, 2, 0, 0, 0, 65, 0]))
    w.close()
    with Reader(tmp_path / "theirs") as r:
        assert [t for _c, t, _raw in r.messages()] == [5]
    assert (len(su._QOS_DUMPS), len(su._QOS_PARSED)) == (n_dumps, n_parsed)
    # their summary is ruamel's: the long type hash folded onto its own line
    assert "type_description_hash: \n" in (tmp_path / "theirs" / "metadata.yaml").read_text()

def test_dp_path_tables_equal_path_walks():
    """The DP kernel's per-state path tables - and, for windows within the revisit window, its path
    bitsets - give the same plans, values and back-pointer choices as walking each candidate's path
    (table_cells=0, bit_words=0), on instances where paths repeat GPs (short revisit time, long
    windows) and where they cannot; GP counts past 64 put the bitsets over several words."""
    import numpy as np
    from dp_instances import random_instance

    from sat_node.scheduler import solve_dp

    repeats = bitsets = 0
    for seed in range(40):
        p = random_instance(seed, n_gp=3 + (seed * 7) % 150, n_steps=60 + 7 * seed, max_window=10 + 4 * seed,
                            revisit_zero_s=[5.0, 12.0, 30.0, 900.0][seed % 4], spread_deg=6.0, prior=seed % 2 == 0)
        walk = solve_dp(p, table_cells=0, bit_words=0)
        for kw in ({}, {"bit_words": 0}):
            a = solve_dp(p, **kw)
            assert np.array_equal(a.steps, walk.steps) and np.array_equal(a.cols, walk.cols), (seed, kw)
            assert np.array_equal(a.values, walk.values) and a.value == walk.value, (seed, kw)
        repeats += len(set(walk.cols.tolist())) < len(walk.cols)
        bitsets += (p.n_steps - 1) * p.step_s < p.revisit_zero_s and p.n_gp > 64
    assert repeats >= 3  # the path-dependent case is exercised
    assert bitsets >= 3  # and the multi-word bitsets


def test_compiled_plan_values_equal_evaluate_plan():
    """dp.plan_value (dp_kernels.plan_values, compiled) gives evaluate_plan's total and per-look values
    bit for bit, on random plans over random instances with priors, repeats of a GP within and past
    the revisit window, looks outside the FOR, and the empty plan."""
    import numpy as np
    from dp_instances import random_instance

    from sat_node.scheduler.dp import plan_value
    from sat_node.scheduler.problem import evaluate_plan

    rng = np.random.default_rng(7)
    zeros = repeats = 0
    for seed in range(30):
        p = random_instance(seed, n_gp=3 + seed % 9, n_steps=40 + 3 * seed, max_window=10 + seed,
                            revisit_zero_s=[5.0, 12.0, 900.0][seed % 3], prior=seed % 2 == 0)
        for size in (0, 1, 4, 12, 30):
            steps = np.sort(rng.choice(p.n_steps, size=min(size, p.n_steps), replace=False))
            cols = rng.integers(0, p.n_gp, size=len(steps))
            a, av = evaluate_plan(p, steps, cols)
            b, bv = plan_value(p, steps, cols)
            assert a == b and av.tobytes() == bv.tobytes(), (seed, size)
            zeros += int((av == 0).sum())
            repeats += len(set(cols.tolist())) < len(cols)
    assert zeros > 50 and repeats > 20  # zero-valued looks and repeats are exercised


def test_dp_plan_values_kept_from_the_check_equal_fresh_ones(monkeypatch):
    """solve_dp values its path once and keeps the numbers for the plan while drop_worthless drops
    nothing (dp.make_plan ``values``); oracle: plan_value of the plan's looks made afresh, and the
    cached cosine thresholds equal the ones computed from the max angles - bit for bit, on
    instances where repeats are dropped and where they are not."""
    import numpy as np
    from dp_instances import random_instance

    from sat_node.scheduler import dp, solve_dp
    from sat_node.scheduler.dp import _max_angles, _slew_limits, plan_value

    dropped = kept = 0
    drop = dp.drop_worthless

    def counted(p, steps, cols, vals=None):
        nonlocal dropped
        out = drop(p, steps, cols, vals)
        dropped += len(out[0]) < len(steps)
        return out

    monkeypatch.setattr(dp, "drop_worthless", counted)
    for seed in range(40):
        p = random_instance(seed, n_gp=3 + (seed * 7) % 60, n_steps=60 + 7 * seed, max_window=10 + 4 * seed,
                            revisit_zero_s=[5.0, 12.0, 30.0, 900.0][seed % 4], spread_deg=6.0, prior=seed % 2 == 0)
        for check in (True, False):
            plan = solve_dp(p, check=check)
            total, vals = plan_value(p, plan.steps, plan.cols)
            assert plan.value == total and plan.values.tobytes() == vals.tobytes(), seed
        kept += len(plan) > 0
        for w in (1, 3, 9):
            a = _max_angles(p.slew, p.step_s, w)
            thr = np.where(a < 0, 2.0, np.cos(np.radians(np.maximum(a - 1e-9, 0.0))))
            assert _slew_limits(p.slew, p.step_s, w)[1].tobytes() == thr.tobytes()
    assert kept >= 30 and dropped >= 2  # plans whose looks were dropped (their values made again) too


def test_compiled_dp_states_equal_the_numpy_ones():
    """dp_kernels.dp_states (one compiled pass over the grid) gives the states of dp._states
    (SchedulingProblem.v_first and pointing in numpy): the same steps, columns, first-visit values
    and unit vectors, bit for bit, on random instances with and without prior observations."""
    import numpy as np
    from dp_instances import random_instance

    from sat_node.scheduler import dp_kernels
    from sat_node.scheduler.dp import _states

    n = 0
    for seed in range(30):
        p = random_instance(seed, n_gp=3 + (seed * 11) % 120, n_steps=40 + 9 * seed, max_window=10 + 4 * seed,
                            revisit_zero_s=[12.0, 900.0][seed % 2], spread_deg=6.0, prior=seed % 3 != 0)
        ref = _states(p)
        got = dp_kernels.dp_states(p.in_for, p.prior_recent, p.absval, p.prior_count, p.sat_pos_km, p.gp_ecef_km)
        assert not got[5]
        for a, b in zip(got[:5], (ref[0], ref[1], ref[2], ref[3], ref[4])):
            assert a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes(), seed
        n += len(ref[0])
    assert n > 1000


def test_dp_states_of_a_forbidden_branch_equal_fresh_ones():
    """The joint planner's branches (joint.with_forbidden: some GPs worth nothing) take their DP
    states from the parent instance's by a mask (sat_node/scheduler/dp.py _prepared); oracle: the
    same branch with that link cut (its states computed from its own arrays) - the same per-state
    arrays bit for bit and the same plan, for forbidden sets small and large."""
    import dataclasses

    import numpy as np
    from dp_instances import random_instance

    from sat_node.scheduler import solve_dp
    from sat_node.scheduler.dp import _prepared
    from sat_node.scheduler.joint import with_forbidden

    rng = np.random.default_rng(4)
    checked = 0
    for seed in range(24):
        p = random_instance(seed, n_gp=3 + (seed * 7) % 90, n_steps=60 + 7 * seed, max_window=10 + 4 * seed,
                            revisit_zero_s=[12.0, 900.0][seed % 2], spread_deg=6.0, prior=seed % 2 == 0)
        solve_dp(p)  # the parent's states are made and kept first, as in the joint planner
        for frac in (0.1, 0.5, 0.9):
            gone = rng.choice(p.gp_ids, size=max(1, int(frac * p.n_gp)), replace=False)
            child = with_forbidden(p, gone.tolist())
            fresh = dataclasses.replace(child, _cache={})
            for a, b in zip(_prepared(child), _prepared(fresh)):
                assert a.dtype == b.dtype and a.tobytes() == b.tobytes(), seed
            x, y = solve_dp(child), solve_dp(fresh)
            assert x.as_list() == y.as_list() and x.value == y.value, seed
            checked += len(x) > 0
    assert checked >= 30


def test_viz_feed_links_equal_contact_scan():
    from types import SimpleNamespace

    from bringup.recording.viz_feed import VizFeed
    from orbit_clock.contact_plan import Contact, ContactPlan

    rng = random.Random(3)
    contacts = []
    for _ in range(400):
        s = rng.choice([rng.uniform(0, 20000), float(rng.randrange(0, 20000, 60))])
        a, b = rng.sample([f"sat_{p}{k}" for p in (1, 2, 3) for k in range(1, 9)], 2)
        contacts.append(Contact(s, s + rng.choice([rng.uniform(1, 3000), 60.0]), a, b, 1000.0, 0.0))
    plan = ContactPlan(contacts)
    feed = VizFeed(SimpleNamespace(isl_plan=plan), period_s=60.0)
    scan_order = sorted(plan.contacts, key=lambda c: c.start_s)  # what the feed scanned before
    seen = 0
    for t in [float(x) for x in range(0, 24000, 60)] + [c.start_s for c in contacts] + [c.end_s for c in contacts]:
        want = [(c.src, c.dst) for c in scan_order if c.start_s <= t < c.end_s]
        assert feed.links_at(t) == want
        seen += len(want)
    assert seen > 1000


def test_unit_vectors_norm_equals_linalg_norm():
    import numpy as np

    from sat_node.acs import unit_vectors

    rng = np.random.default_rng(2)
    for shape in [(3,), (1, 3), (17, 3), (40, 25, 3), (5, 1, 3)]:
        v = rng.normal(size=shape) * 10.0 ** rng.integers(-3, 5, size=shape)
        want = v / np.linalg.norm(v, axis=-1, keepdims=True)
        assert unit_vectors(v).tobytes() == want.tobytes()


def test_batched_envelope_writes_are_byte_identical(tmp_path):
    """write_envelopes (the local engine's per-step call) gives rosbags' own file, whatever the batch
    sizes (1, odd, larger than a chunk), including a batch holding a topic's first envelope."""
    _slow_bag(tmp_path / "slow" / "bag")
    b = (tmp_path / "slow" / "bag" / "bag.mcap").read_bytes()
    for name, sizes in (("a", [1]), ("b", [7, 300, 1]), ("c", [40000])):
        _write_batched(tmp_path / name / "bag", sizes)
        assert (tmp_path / name / "bag" / "bag.mcap").read_bytes() == b, name
        assert ((tmp_path / name / "bag" / "metadata.yaml").read_text()
                == (tmp_path / "slow" / "bag" / "metadata.yaml").read_text())


def test_batched_writes_reject_bad_envelopes_like_single_writes(tmp_path):
    import pytest

    with BagWriter(tmp_path / "bag") as bag:
        bag.write_envelopes([Envelope(5, "x", 0, "/a", "ok")])
        with pytest.raises(ValueError, match="log time must be >= 0"):
            bag.write_envelopes([Envelope(6, "x", 1, "/a", "ok"), Envelope(-1, "x", 2, "/a", "bad")])
    with BagReader(tmp_path / "bag") as r:
        assert [(e.t_ns, e.seq) for e in r.envelopes()] == [(5, 0), (6, 1)]


def test_wire_encoder_equals_encode_envelope_bytes():
    from msgs_json.wire import WireEncoder, decode_envelope, encode_envelope_bytes

    rng = random.Random(3)
    texts = ["", "plain", 'q"uote\\back', "tab\tnl\nctl\x01", "ünï\u2028cødé\U0001f600", "</script>"]
    payloads = [bytes(rng.randrange(256) for _ in range(rng.randrange(0, 40))) for _ in range(30)]
    enc = WireEncoder(cache_max=8)  # small: the cache is cleared many times
    for i in range(3000):
        data = rng.choice(payloads) if rng.random() < 0.5 else rng.choice(texts) + str(i)
        env = Envelope(rng.choice([0, 1, 10**18, rng.randrange(10**15)]), rng.choice(texts[1:] + ["sat_11"]),
                       rng.randrange(0, 10**9), "/t", data)
        got = enc(env)
        assert got == encode_envelope_bytes(env)
        assert decode_envelope(got, "/t") == env
    odd = Envelope(True, "s", 1, "/t", "x")  # not an int: the plain encoder decides
    assert enc(odd) == encode_envelope_bytes(odd)


def test_engine_hands_steps_to_write_envelopes(tmp_path):
    """A BagWriter sink gets each step's list (write_envelopes); the bag equals one made by a sink
    that writes envelope by envelope."""
    from bringup.engine.local import LocalEngine, run_local
    from msgs_json.envelope import Emit, StepResult

    class Talker:
        def __init__(self, name):
            self.name = name

        def subscriptions(self):
            return ["/chat"]

        def start(self, t0):
            return StepResult([Emit("/chat", f"hi from {self.name}", t0)], t0 + 10)

        def step(self, t, inbox):
            return StepResult([Emit("/chat", f"{self.name} saw {len(inbox)}", t),
                               Emit(f"/{self.name}/raw", bytes([len(inbox) % 256]) * 3, t)], t + 7)

        def finish(self, t):
            return [Emit("/chat", "bye", t)]

    with BagWriter(tmp_path / "a" / "bag") as bag:
        eng = LocalEngine([Talker("p"), Talker("q")], horizon_ns=500, max_step_ns=100, sink=bag.write_envelope,
                          sink_many=bag.write_envelopes)
        assert eng._sink_many is not None
        ra = eng.run()
    with BagWriter(tmp_path / "b" / "bag") as bag:
        rb = run_local([Talker("p"), Talker("q")], horizon_ns=500, max_step_ns=100,
                       sink=lambda e: bag.write_envelope(e))
    assert ra.counts_by_topic == rb.counts_by_topic and ra.steps == rb.steps
    assert (tmp_path / "a" / "bag" / "bag.mcap").read_bytes() == (tmp_path / "b" / "bag" / "bag.mcap").read_bytes()
    with BagReader(tmp_path / "a" / "bag") as r:
        assert sum(1 for _ in r.envelopes()) == sum(ra.counts_by_topic.values()) > 100


def test_one_satellite_positions_equal_the_mixed_path():
    import numpy as np

    from orbit_clock.propagation import build_constellation
    from bringup.scenario.config import load_scenario

    c = build_constellation(load_scenario("paper"))
    t = np.array([0.0, 12.345, 3600.5, 21599.999, 7.0])
    for i in (0, 5, len(c) - 1):
        one = c.positions_ecef_km_at(np.full(t.size, i), t)  # the one-satellite path
        other = (i + 1) % len(c)
        mixed = c.positions_ecef_km_at(np.r_[np.full(t.size, i), other], np.r_[t, 1.0])  # the grouped path
        assert np.array_equal(one, mixed[:t.size])  # bit for bit
        assert np.array_equal(c.positions_ecef_km_at(np.array([i]), t[2:3]), one[2:3])


def test_isl_runs_kernel_equals_numpy_margin(paper_scenario):
    """orbit_clock/isl_kernels.py: the compiled runs of positive margin within random spans equal
    the runs of numpy's margin (orbit_clock/isl.py ``_margin``, every pair at every sample) cut to
    the same spans - with one range per pair, several spans per pair and spans at the grid's ends."""
    import numpy as np

    from orbit_clock import build_constellation
    from orbit_clock.isl import _margin, _runs_in_segments
    from orbit_clock.windows import time_grid, true_runs

    sc = paper_scenario.with_overrides(sats=96, planes=6, hours=1.0)
    c = build_constellation(sc)
    t = time_grid(0.0, sc.scenario.horizon_s, 10.0)
    r = c.positions_ecef_km(t)
    n = len(c)
    I, J = np.triu_indices(n, k=1)
    rng = np.random.default_rng(3)
    lim = rng.uniform(2000.0, 7000.0, I.size)
    inside = _margin(r[I], r[J], 80.0, lim[:, None]) > 0  # (pairs, samples), numpy
    pair, first, last = [], [], []
    for p in np.sort(rng.choice(np.flatnonzero(inside.any(axis=1)), 600, replace=False)):
        edges = np.sort(rng.choice(t.size, 4, replace=False))
        for a, b in ((edges[0], edges[1]), (edges[2], edges[3])):
            pair.append(p), first.append(a), last.append(b)
    pair.append(I.size - 1), first.append(0), last.append(t.size - 1)  # a whole-grid span
    pair, first, last = (np.array(x, dtype=np.int64) for x in (pair, first, last))
    want_si, want_ks, want_ke = [], [], []
    for p, a, b in zip(pair, first, last):
        _s, ks, ke = true_runs(inside[p:p + 1, a:b + 1])
        want_si += [p] * ks.size
        want_ks += list(ks + a)
        want_ke += list(ke + a)
    order = np.lexsort((want_ks, want_si))
    want = [np.array(x, dtype=np.int64)[order] for x in (want_si, want_ks, want_ke)]
    got = _runs_in_segments(r, I, J, pair, first, last, 80.0, lim)
    assert len(want[0]) > 300
    assert all(np.array_equal(g, w) for g, w in zip(got, want, strict=True))


def test_pruned_isl_windows_equal_every_pair_at_every_sample(paper_scenario):
    """orbit_clock/isl.py: sampling only the pairs and times a k-d tree finds within reach gives the
    windows of the plain search (every pair at every grid sample), bit for bit - and samples less."""
    import numpy as np

    from orbit_clock import build_constellation
    from orbit_clock.isl import _candidate_segments, isl_windows
    from orbit_clock.windows import time_grid

    for sats, planes, hours in ((24, 3, 6.0), (96, 6, 2.0), (60, 60, 1.0)):
        sc = paper_scenario.with_overrides(sats=sats, planes=planes, hours=hours)
        c = build_constellation(sc)
        h = sc.scenario.horizon_s
        fast = isl_windows(c, 0.0, h, prune=True)
        plain = isl_windows(c, 0.0, h, prune=False)
        assert len(fast[0]) > 50
        assert all(np.array_equal(x, y) for x, y in zip(fast, plain, strict=True))
        t = time_grid(0.0, h, 10.0)
        _pair, first, last = _candidate_segments(c, t, c.positions_ecef_km(t), sc.isl.max_range_km)
        if sats >= 96:
            assert (last - first + 1).sum() < 0.6 * sats * (sats - 1) / 2 * t.size



def test_isl_mean_range_in_blocks_equals_one_block(paper_scenario, monkeypatch):
    """orbit_clock/isl.py isl_contact_plan: the windows' mean ranges (light times) computed in blocks
    of windows equal those of all windows at once, contact for contact."""
    from orbit_clock import build_constellation, isl
    from orbit_clock.isl import isl_contact_plan

    sc = paper_scenario.with_overrides(sats=96, planes=6, hours=1.0)
    c = build_constellation(sc)
    monkeypatch.setattr(isl, "_MEAN_BLOCK", 10**9)
    whole = isl_contact_plan(sc, c)
    monkeypatch.setattr(isl, "_MEAN_BLOCK", 7)
    blocks = isl_contact_plan(sc, c)
    assert len(whole) > 1000
    assert blocks.contacts == whole.contacts


def test_named_tuples_made_from_their_fields_equal_constructed_ones(tmp_path):
    """bringup/engine/local.py (Envelope), orbit_clock/contact_announcer.py (Emit), dtn_router/link.py
    (Copy) make their named tuples with tuple.__new__: the same type, fields and equality as the
    class called with the fields; and what the engine hands on is of the type the bag writer reads."""
    from bringup.engine.local import run_local
    from dtn_router.link import Copy, LinkModel
    from msgs_json.envelope import Emit, Envelope, StepResult
    from orbit_clock.contact_announcer import ContactAnnouncer
    from orbit_clock.contact_plan import Contact, ContactPlan

    for cls, fields in ((Envelope, (5, "sat_11", 3, "/t", b"\x00x")), (Emit, ("/t", "text", 7)), (Copy, ("sat_12", 9))):
        made = tuple.__new__(cls, fields)
        assert type(made) is cls and made == cls(*fields) and made._asdict() == cls(*fields)._asdict()
    plan = ContactPlan([Contact(0.0, 50.0, "sat_11", "sat_12", 1e4, 0.01),
                        Contact(0.0, 50.0, "sat_11", "sat_13", 1e4, 0.02)])
    out = LinkModel(plan).transmit("sat_11", "sat_12", 10**9, 2000)
    assert out.ok and [type(c) for c in out.copies] == [Copy, Copy]
    assert out.copies == [Copy("sat_12", 10**9 + 2 * 10**8 + 10**7), Copy("sat_13", 10**9 + 2 * 10**8 + 2 * 10**7)]

    class Talker:
        name = "talker"

        def subscriptions(self):
            return []

        def start(self, t0_ns):
            return StepResult([Emit("/x", "a", t0_ns)], 10)

        def step(self, t_ns, inbox):
            return StepResult([Emit("/x", b"b", t_ns)], None)

        def finish(self, t_ns):
            return []

    res = run_local([Talker(), ContactAnnouncer(plan)], horizon_ns=60 * 10**9, max_step_ns=10**10)
    assert res.envelopes and all(type(e) is Envelope for e in res.envelopes)
    assert res.envelopes[0] == Envelope(0, "contacts", 0, "/orbit/contacts", res.envelopes[0].data)
    assert [e for e in res.envelopes if e.source == "talker"][:2] == [Envelope(0, "talker", 0, "/x", "a"),
                                                                       Envelope(0, "talker", 1, "/x", b"b")]
