"""bringup/recording/metadata_yaml.py: libyaml's dump reads back as the same mapping in every
reader, and its load gives what ruamel.yaml's safe loader gives.

Oracles: ruamel.yaml's safe loader (rosbags' reader; YAML 1.2) and PyYAML's safe loader (YAML 1.1
rules), on a bag's real summary and on hypothesis-drawn mappings whose strings are drawn to look
like numbers, booleans, nulls and dates; and ruamel itself on scalars of every plain form and on the
documents the fast loader hands over.
"""

from __future__ import annotations

import math
from io import StringIO

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from ruamel.yaml import YAML

from bringup.recording import metadata_yaml as my
from bringup.recording.bag import BagWriter

pytestmark = pytest.mark.skipif(not my.LIBYAML, reason="PyYAML without libyaml: metadata_yaml is ruamel itself")


def _ruamel_load(text):
    return YAML(typ="safe").load(text)


def _ruamel_dump(data) -> str:
    y = YAML(typ="safe")
    y.default_flow_style = False
    s = StringIO()
    y.dump(data, s)
    return s.getvalue()


def _pyyaml_load(text):
    return yaml.load(text, Loader=yaml.SafeLoader)  # the pure-Python YAML 1.1 safe loader


def _outcome(fn, text):
    try:
        return ("ok", repr(fn(text)))
    except Exception as exc:  # noqa: BLE001 - the error itself is what is compared
        return ("error", type(exc).__name__, str(exc))


def _summary_of_a_bag(path, custom: dict, n_topics: int) -> str:
    """metadata.yaml of a bag written through rosbags' own paths (ruamel's text)."""
    with BagWriter(path, custom=custom, epoch_ns=946727968 * 10**9, fast_off=True) as bag:
        for i in range(n_topics):
            bag.write_raw(f"/sat_{i:04d}/dtn/in", "std_msgs/msg/String", bytes([0, 1, 0, 0, 2, 0, 0, 0, 65, 0]), i)
    return (path / "metadata.yaml").read_text()


def test_a_bag_summary_dumps_and_loads_as_ruamel_does(tmp_path):
    """A 100-topic summary (QoS sequences, type hashes past 80 columns): libyaml's text differs from
    ruamel's only in where the long hashes sit, and loads equal in every reader."""
    text = _summary_of_a_bag(tmp_path / "bag", {"scenario": "paper"}, 100)
    data = _ruamel_load(text)
    assert len(data["rosbag2_bagfile_information"]["topics_with_message_count"]) == 100
    assert my.load(text) == data == _pyyaml_load(text)
    mine = my.dumps(data)
    assert mine != text  # not ruamel's bytes...
    assert _ruamel_load(mine) == _pyyaml_load(mine) == my.load(mine) == data  # ...the same mapping
    folded = text.replace("type_description_hash: \n        RIHS01_", "type_description_hash: RIHS01_")
    assert folded == mine  # the hashes' line breaks are the only difference


def test_strings_that_look_like_other_things_are_quoted_for_every_reader(tmp_path):
    """ruamel writes ``yes: on`` and ``sx: 1:20`` plain (strings in YAML 1.2), which a YAML 1.1
    reader takes for ``True: True`` and 80; libyaml's dump quotes them, so all three readers agree."""
    custom = {"n": "0o17", "yes": "on", "date": "2000-01-01", "e": "1e3", "sx": "1:20", "o": "017"}
    text = _summary_of_a_bag(tmp_path / "bag", custom, 2)
    data = _ruamel_load(text)
    assert {k: data["rosbag2_bagfile_information"]["custom_data"][k] for k in custom} == custom
    assert _pyyaml_load(text) != data  # rosbags' own text, read with YAML 1.1 rules
    mine = my.dumps(data)
    assert _ruamel_load(mine) == _pyyaml_load(mine) == my.load(mine) == data


_LOOKALIKES = ["yes", "No", "on", "OFF", "y", "n", "~", "null", "NULL", "", "0o17", "017", "0x1F", "0b101", "1_000",
               "1:20", "1:20.5", "1e3", "1.5e3", "-1E-3", ".5", ".inf", "-.Inf", ".NaN", "2001-12-14",
               "2001-12-14t21:59:43.10-05:00", "=", "<<", "True", "+12", "-0", "0", "+.5e+3", "1.", "._5", "_",
               "- a", "a: b", "#x", "x #y", "&a", "*a", "!t", "%p", "@", "`", "'q", '"q', "[", "{", "|", ">", "?",
               " lead", "trail ", "tab\tin", "line\nbreak", "RIHS01_" + "ab" * 32, "ünï", "\x85", "\u2028"]
_scalar_text = st.one_of(st.sampled_from(_LOOKALIKES),
                         st.text(alphabet=st.sampled_from(list("0123456789+-._:eEoxbtTfFnNyY~ ")), max_size=8),
                         st.text(alphabet=st.characters(blacklist_categories=("Cs",)), max_size=12))
_scalars = st.one_of(_scalar_text, st.integers(min_value=-(2**70), max_value=2**70), st.booleans(), st.none(),
                     st.floats(allow_nan=False))
_docs = st.recursive(_scalars, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                       st.dictionaries(_scalar_text, inner, max_size=4)),
                     max_leaves=20)


def _same(a, b) -> bool:
    """Equal, with -0.0 and 0.0 told apart (a float's sign survives a dump)."""
    if isinstance(a, float) and isinstance(b, float):
        return a == b and math.copysign(1, a) == math.copysign(1, b)
    if type(a) is not type(b):
        return False
    if isinstance(a, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    return a == b


@settings(max_examples=400, deadline=None)
@given(_docs)
def test_dump_reads_back_the_same_in_every_reader(data):
    text = my.dumps(data)
    for load in (_ruamel_load, _pyyaml_load, my.load):
        assert _same(load(text), data), (load.__name__, text)


def test_shared_objects_are_written_out_not_aliased():
    shared = {"sec": 0, "nsec": 0}
    text = my.dumps({"deadline": shared, "lifespan": shared})
    assert "&" not in text and "*" not in text and _ruamel_load(text) == {"deadline": shared, "lifespan": shared}


@pytest.mark.parametrize("scalar", _LOOKALIKES)
def test_load_resolves_plain_scalars_as_ruamel(scalar):
    if scalar and (scalar[0] in "-#&*!%@`'\"[{|>?:" or "\n" in scalar or scalar != scalar.strip()):
        doc = f"k: {my.dumps(scalar).strip()}\n"  # not a plain scalar: quoted
    else:
        doc = f"k: {scalar}\n"
    assert _outcome(my.load, doc) == _outcome(_ruamel_load, doc)


@pytest.mark.parametrize("doc", [
    "a: 1\na: 2\n",  # a duplicate key: ruamel refuses it
    "b: &x {c: 1}\nd:\n  <<: *x\n  e: 2\n",  # a merge key
    "%YAML 1.1\n---\nk: yes\n",  # 1.1 rules: ruamel reads a boolean
    "k: !!str 5\n", "k: !!float 1:20\n", "k: !!binary aGk=\n", "k: !foo bar\n",
    "k: 2001-12-14\n", "k: =\n", "{1: a, 0x1: b}\n",
    "k: [1, 2\n", "{{{ not yaml", "a: 1\n---\nb: 2\n", "", "? [1, 2]\n: x\n",
])
def test_what_is_handed_over_gets_ruamels_answer(doc):
    assert _outcome(my.load, doc) == _outcome(_ruamel_load, doc)


_TOKENS = ["a", "b", ":", ": ", "- ", "\n", "\n  ", "\n    ", " ", "'", '"', "[", "]", "{", "}", ",", "#", " #",
           "&x ", "*x", "? ", "|", ">", "|-", ">+", "1", "0o7", "yes", "~", "null", "-", ".", "e3", "\\", "\\n",
           "\u00e9", "\r", "\r\n", "---", "...", "x: y", "1:2", "=", "<<", "!", "%", "@", "\t", "\x07", "\x00",
           "\x85", "\u2028", "\ufeff", "\U0001F600", "\ufffe", "\x7f", "\n- ", "\n  - ", "\nk2: ", "\n  k3: "]


@settings(max_examples=1000, deadline=None)
@given(st.sampled_from(["", "k: ", "k:\n  ", "k:\n- ", "rosbag2_bagfile_information:\n  a: 1\n  "]),
       st.lists(st.sampled_from(_TOKENS), max_size=16).map("".join))
def test_load_gives_ruamels_answer_on_drawn_documents(head, rest):
    """Documents drawn from YAML's indicators, scalars of every kind and the characters where
    libyaml and ruamel part (tabs, NEL, BOM, CR, tags, anchors, block scalars, document markers):
    the same mapping, or ruamel's own error."""
    doc = head + rest
    assert _outcome(my.load, doc) == _outcome(_ruamel_load, doc)


def test_without_libyaml_it_is_ruamel(monkeypatch):
    data = {"x": ["0o17", 1, None, {"h": "RIHS01_" + "ab" * 32}]}
    monkeypatch.setattr(my, "LIBYAML", False)
    assert my.dumps(data) == _ruamel_dump(data)  # ruamel's bytes
    from bringup.recording import rosbags_speedups as su

    su.install()
    import rosbags.rosbag2.writer as w

    with su.metadata_yaml():
        assert isinstance(w.YAML(typ="safe"), YAML)  # rosbags gets ruamel's own object
