"""A bag's metadata YAML written and read through libyaml, as ruamel.yaml reads it.

What it is: rosbag2's bag summary, metadata format version 9 - one ``rosbag2_bagfile_information``
mapping (version, storage_identifier, relative_file_paths, duration, starting_time, message_count,
one ``topics_with_message_count`` entry per topic with its ``offered_qos_profiles`` as a YAML
sequence, compression, files, custom_data, ros_distro; https://github.com/ros2/rosbag2
``rosbag2_storage/include/rosbag2_storage/yaml.hpp``). A bag holds it twice: ``metadata.yaml``, and
the MCAP file's ``rosbag2`` Metadata record (opcode 0x0C, key ``serialized_metadata``;
https://mcap.dev/spec), which readers of the ``.mcap`` alone see (Foxglove lists it with the file's
metadata). rosbags writes both with ruamel.yaml's
safe dumper and reads metadata.yaml with ruamel's safe loader, pure Python: ~2.2 s per dump and
~3 s per load of the ~940 KB summary of a 240-satellite run. libyaml (PyYAML's C dumper and
parser, a pinned dependency) does each in ~0.3 s.

Readers and what they need: rosbag2 reads the file with yaml-cpp (scalars are untyped text,
converted with ``as<T>()``: only the keys, the nesting and each scalar's text matter); rosbags and
this project read it with ruamel.yaml (YAML 1.2 core schema: ``yes``, ``on``, ``1:20`` are
strings, ``0o17`` and ``1e3`` are numbers); PyYAML users with YAML 1.1 rules (the opposite on those
examples).

* :func:`dump` - the libyaml emitter with PyYAML's safe representer; a string is written plain
  only when neither YAML 1.1 (PyYAML's resolver) nor YAML 1.1 or 1.2 as ruamel resolves them would
  read that plain scalar as anything but a string, so every one of those readers gets the mapping
  that was dumped; no anchors or aliases. The text is not ruamel's byte for byte: on a 240-satellite
  summary the one difference is that ruamel moves a long plain scalar that does not fit in 80
  columns (``type_description_hash: RIHS01_<64 hex digits>``, 71 characters after a key that
  ends in column 29) to the next line, indented, and
  libyaml keeps it on the key's line. Both are the same YAML document.
* :func:`load` - the libyaml parser, resolving plain scalars with ruamel's own YAML 1.2 patterns
  (``ruamel.yaml.resolver.implicit_resolvers``) in ruamel's order and building ints as ruamel's
  1.2 rules do (``0o`` octal, leading zeros decimal). A document with something the two parsers
  do not read alike is handed to ruamel, which decides - its mapping, its error and its message:
  a ``%`` directive line (``%YAML 1.1`` switches ruamel to 1.1 rules), a ``...`` line, a tag
  (``!``), an anchor or alias (``&``, ``*``), a block scalar (``|``, ``>``), a tab, CR, NEL,
  U+2028/2029 or BOM (each found where libyaml and ruamel part by drawing documents from YAML's
  indicators), a timestamp, a merge key ``<<``, a duplicate key (ruamel refuses them) and any
  error at all. A bag summary has none of these (the type hashes, names and numbers of every
  topic, and the project's custom data), so it takes the fast path.

Without libyaml (``yaml.__with_libyaml__`` False) both go to ruamel.yaml, as rosbags does.

How we know it is right: tests/unit/test_metadata_yaml.py - a 100-topic summary and hypothesis-drawn
mappings (strings drawn to look like numbers, booleans, nulls, dates) dumped here load equal with
ruamel, with PyYAML's YAML 1.1 safe loader and with :func:`load`; scalars in every plain form and
documents drawn from YAML's indicators load as ruamel loads them (or fail with ruamel's error); and
tests/unit/test_speed_paths.py opens a bag written with and without this dump through rosbags'
Reader (metadata, topics, counts, QoS equal) and the ``mcap`` reader (the same record's mapping).
"""

from __future__ import annotations

import re
from io import StringIO
from typing import Any, ClassVar, TextIO

import yaml
from ruamel.yaml import YAML as _RuamelYAML
from ruamel.yaml.resolver import implicit_resolvers as _RUAMEL_RESOLVERS

__all__ = ["LIBYAML", "dump", "dumps", "load"]

LIBYAML: bool = bool(getattr(yaml, "__with_libyaml__", False))

_MERGE = "tag:yaml.org,2002:merge"
_TIMESTAMP = "tag:yaml.org,2002:timestamp"
_VALUE = "tag:yaml.org,2002:value"


class _HandOver(Exception):
    """The document has something the fast loader does not read as ruamel does: ruamel reads it."""


def _ruamel_patterns(version: tuple[int, int] | None):
    for versions, tag, regexp, first in _RUAMEL_RESOLVERS:
        if version is None or version in versions:
            yield tag, re.compile(regexp.pattern, regexp.flags), first


# -- dumping -------------------------------------------------------------------------------------------
if LIBYAML:
    class _Dumper(yaml.CSafeDumper):
        """PyYAML's resolver (YAML 1.1) plus ruamel's YAML 1.1 and 1.2 patterns: used only to decide
        whether a string can be written plain (it must resolve to nothing but str in every reader)."""

        def ignore_aliases(self, data) -> bool:
            return True

    for _tag, _rx, _first in _ruamel_patterns(None):
        _Dumper.add_implicit_resolver(_tag, _rx, _first)


def _ruamel_dump(data: Any, stream: TextIO) -> None:
    y = _RuamelYAML(typ="safe")
    y.default_flow_style = False
    y.dump(data, stream)


def dump(data: Any, stream: TextIO) -> None:
    """Write ``data`` (dicts, lists, str, int, bool, None) to ``stream`` as block-style YAML."""
    if not LIBYAML:
        _ruamel_dump(data, stream)
        return
    try:
        text = yaml.dump(data, Dumper=_Dumper, default_flow_style=False, allow_unicode=True, sort_keys=True)
    except yaml.YAMLError:  # a type the safe representer does not know: ruamel's verdict
        _ruamel_dump(data, stream)
        return
    stream.write(text)


def dumps(data: Any) -> str:
    s = StringIO()
    dump(data, s)
    return s.getvalue()


# -- loading -------------------------------------------------------------------------------------------
if LIBYAML:
    class _Loader(yaml.CSafeLoader):
        """libyaml's parser; plain scalars resolved with ruamel's YAML 1.2 patterns, in its order."""

        yaml_implicit_resolvers: ClassVar[dict] = {}  # its own table, filled below

        def construct_yaml_int(self, node):  # ruamel's rules for YAML 1.2
            v = self.construct_scalar(node).replace("_", "")
            sign = -1 if v[0] == "-" else 1
            if v[0] in "+-":
                v = v[1:]
            if v == "0":
                return 0
            for prefix, base in (("0b", 2), ("0x", 16), ("0o", 8)):
                if v.startswith(prefix):
                    return sign * int(v[2:], base)
            return sign * int(v)

        def construct_mapping(self, node, deep=False):
            if any(k.tag == _MERGE for k, _v in node.value):
                raise _HandOver("merge key")
            m = super().construct_mapping(node, deep=deep)
            if len(m) != len(node.value):
                raise _HandOver("duplicate key")
            return m

        def hand_over(self, node):
            raise _HandOver(node.tag)

    for _tag, _rx, _first in _ruamel_patterns((1, 2)):
        _Loader.add_implicit_resolver(_tag, _rx, _first)
    _Loader.add_constructor("tag:yaml.org,2002:int", _Loader.construct_yaml_int)
    for _tag in (_TIMESTAMP, _VALUE, "tag:yaml.org,2002:yaml"):
        _Loader.add_constructor(_tag, _Loader.hand_over)

_HANDED_OVER = re.compile("^%|^[.][.][.]|[!|>&*\r\t\x85\u2028\u2029\ufeff]", re.MULTILINE)


def _ruamel_load(text: str) -> Any:
    return _RuamelYAML(typ="safe").load(text)


def load(text: str) -> Any:
    """What ``ruamel.yaml.YAML(typ="safe").load(text)`` returns (or raises), read with libyaml where
    that is known to give the same (module docstring)."""
    if not LIBYAML or _HANDED_OVER.search(text):
        return _ruamel_load(text)
    try:
        return yaml.load(text, Loader=_Loader)  # a safe loader: CSafeLoader's constructors
    except Exception:  # noqa: BLE001 - _HandOver or any error: ruamel decides, with its own message
        return _ruamel_load(text)
