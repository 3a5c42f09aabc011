"""Encode/decode msgs_json payloads with validation (docs/design.md section 4).

``encode(msg) -> str`` gives the JSON text of a schema instance (msgs_json/schemas.py);
``decode(topic, text) -> Struct`` parses and validates a payload received on ``topic`` (its type
from msgs_json/topics.py); ``decode_as(tp, text, where)`` does the same for a given type. Any
malformed input (not JSON, wrong type, out-of-range field, broken invariant, unknown field, wrong
schema version, not even text) raises :class:`MessageError` whose one-line message names the topic
and the field path, e.g. ``/sat_11/schedule: $.items[2].t_ns: Expected int >= 0``. Nodes catch
MessageError, count the message as rejected and carry on: never a crash.

Oracle: golden JSON per type re-encodes to the same bytes; hypothesis fuzzing (random bytes, random
JSON, mutated goldens) never raises anything but MessageError (tests/unit/test_msgs_json.py).
"""

from __future__ import annotations

from typing import Any

import msgspec

from msgs_json.topics import is_bytes_topic, schema_for

__all__ = ["MessageError", "decode", "decode_as", "encode", "encode_bytes"]


class MessageError(ValueError):
    """A payload that does not fit its schema; the message names topic and field, on one line."""


_encoder = msgspec.json.Encoder()
_decoders: dict[Any, msgspec.json.Decoder] = {}


_by_id: dict[int, tuple[Any, msgspec.json.Decoder]] = {}


def _decoder(tp: Any) -> msgspec.json.Decoder:
    # by identity first: hashing a typing construct (Union, Annotated) costs microseconds, and the
    # same schema object comes back for every message of a topic
    hit = _by_id.get(id(tp))
    if hit is not None and hit[0] is tp:
        return hit[1]
    d = _decoders.get(tp)
    if d is None:
        d = _decoders[tp] = msgspec.json.Decoder(tp)
    _by_id[id(tp)] = (tp, d)
    return d


def encode_bytes(msg: msgspec.Struct) -> bytes:
    """UTF-8 JSON of a schema instance."""
    return _encoder.encode(msg)


def encode(msg: msgspec.Struct) -> str:
    """JSON text of a schema instance (what goes in an envelope's ``body``)."""
    return _encoder.encode(msg).decode("utf-8")


def _one_line(s: str) -> str:
    return " ".join(str(s).split())


def decode_as(tp: Any, text: str | bytes, where: str) -> Any:
    """Decode ``text`` as ``tp``; MessageError naming ``where`` and the field on any failure."""
    if not isinstance(text, (str, bytes, bytearray, memoryview)):
        raise MessageError(f"{where}: payload must be JSON text, got {type(text).__name__}")
    try:
        return _decoder(tp).decode(text)
    except msgspec.ValidationError as exc:
        # msgspec: "<what> - at `$.path`"; put the path first.
        msg = _one_line(str(exc))
        what, sep, path = msg.rpartition(" - at ")
        if sep:
            msg = f"{path.strip('`')}: {what}"
        raise MessageError(f"{where}: {msg}") from None
    except msgspec.DecodeError as exc:
        raise MessageError(f"{where}: not valid JSON: {_one_line(str(exc))}") from None
    except (UnicodeError, ValueError, TypeError, OverflowError, RecursionError) as exc:
        raise MessageError(f"{where}: bad payload: {_one_line(str(exc))[:200]}") from None


def decode(topic: str, text: str | bytes) -> Any:
    """Decode and validate a JSON payload received on ``topic``."""
    if is_bytes_topic(topic):
        raise MessageError(f"{topic}: carries raw bytes (BPv7 bundles), not a JSON payload")
    tp = schema_for(topic)
    if tp is None:
        raise MessageError(f"{topic}: unknown topic (no msgs_json schema)")
    return decode_as(tp, text, topic)
