"""Wire form of a lockstep envelope (msgs_json/envelope.py) on a ROS 2 topic and in the bag.

Every lockstep data topic carries ``std_msgs/msg/String`` whose ``data`` is one JSON object::

    {"t_ns": <int>, "src": "<participant>", "seq": <int>, "body": "<payload>"}            # JSON topics
    {"t_ns": <int>, "src": "<participant>", "seq": <int>, "b64": "<base64 of bytes>"}    # byte topics

On DDS a run's envelopes also carry ``"mac"``, their MAC under the run key (msgs_json/auth.py); the
recorder checks it and records the envelope without it, so a bag holds exactly the form above.

``body`` is the payload's own JSON text (validated by its msgs_json schema when decoded by the
receiver); ``b64`` carries raw bytes (BPv7 bundles) in standard base64. The same text is what the
MCAP bag records, with log time = ``t_ns``, so a bag can be turned back into envelopes exactly.

Oracle: round trip tests (encode -> decode is identity for str and bytes payloads) and rejection
tests (every malformed wire text raises WireError with one line saying what is wrong);
On DDS the String goes as its CDR bytes (:func:`string_cdr`, :func:`string_from_cdr`: OMG CDR
with the 4-byte encapsulation header, as rclpy serializes std_msgs/msg/String); the ROS engine
publishes and reads them raw, and the bag records the same bytes. ``without_mac`` gives the
recorded form of a received text whose MAC verified (its ``mac`` field cut off).

``WireEncoder`` (the bag writer's cached encoder) gives the bytes of ``encode_envelope_bytes`` on
random envelopes with escapes, non-ASCII text and a small cache (tests/unit/test_speed_paths.py).
"""

from __future__ import annotations

import base64
import binascii
import struct

import msgspec

from msgs_json.envelope import Envelope

__all__ = ["WireEncoder", "WireError", "decode_envelope", "decode_envelope_mac", "encode_envelope",
           "encode_envelope_bytes", "string_cdr", "string_from_cdr", "without_mac"]


class WireError(ValueError):
    """A wire text that is not a valid envelope; the message says what is wrong."""


class _Wire(msgspec.Struct, forbid_unknown_fields=True, omit_defaults=True):
    t_ns: int
    src: str
    seq: int
    body: str | None = None
    b64: str | None = None
    mac: str | None = None


_enc = msgspec.json.Encoder()
_dec = msgspec.json.Decoder(_Wire)


def encode_envelope(env: Envelope, mac: str | None = None) -> str:
    """The wire text of ``env``; ``mac``: its MAC under the run key (msgs_json/auth.py), on DDS."""
    if isinstance(env.data, bytes):
        w = _Wire(env.t_ns, env.source, env.seq, b64=base64.b64encode(env.data).decode("ascii"), mac=mac)
    else:
        w = _Wire(env.t_ns, env.source, env.seq, body=env.data, mac=mac)
    return _enc.encode(w).decode("utf-8")


def encode_envelope_bytes(env: Envelope) -> bytes:
    """``encode_envelope(env).encode("utf-8")`` without the round trip through str (the bag writer's
    path: ~450k envelopes per paper run)."""
    d = env.data
    if type(d) is bytes or isinstance(d, bytes):
        return _enc.encode(_Wire(env.t_ns, env.source, env.seq, b64=_b64(d).decode("ascii")))
    return _enc.encode(_Wire(env.t_ns, env.source, env.seq, body=d))


_b64 = base64.b64encode

# The same JSON as _enc.encode(_Wire(...)): msgspec writes a Struct's fields in declaration order,
# omits the None defaults, writes ints in decimal and each str as its own JSON string, which is
# what _enc.encode(str) gives (tests/unit/test_msgs_json.py compares both on random envelopes).
_J_B64 = b'{"t_ns":%d,"src":%b,"seq":%d,"b64":"%b"}'
_J_BODY = b'{"t_ns":%d,"src":%b,"seq":%d,"body":%b}'


class WireEncoder:
    """``encode_envelope_bytes`` for a stream of envelopes (the bag writer), with two caches: the
    JSON string of each source name, and the base64 text of recent byte payloads (a bundle the
    router hands to k neighbours is the same bytes k+1 times in a paper run: 322k byte envelopes,
    59k distinct). Same bytes out as ``encode_envelope_bytes`` for every envelope."""

    def __init__(self, cache_max: int = 16384):
        self.cache_max = int(cache_max)
        self._src: dict[str, bytes] = {}
        self._b64: dict[bytes, bytes] = {}

    def __call__(self, env: Envelope) -> bytes:
        t, seq, d = env.t_ns, env.seq, env.data
        src = self._src.get(env.source)
        if src is None:
            if type(env.source) is not str:
                return encode_envelope_bytes(env)
            src = self._src[env.source] = _enc.encode(env.source)
        if type(t) is not int or type(seq) is not int:
            return encode_envelope_bytes(env)
        td = type(d)
        if td is bytes:
            b = self._b64.get(d)
            if b is None:
                if len(self._b64) >= self.cache_max:
                    self._b64.clear()
                b = self._b64[d] = _b64(d)
            return _J_B64 % (t, src, seq, b)
        if td is str:
            return _J_BODY % (t, src, seq, _enc.encode(d))
        return encode_envelope_bytes(env)


def decode_envelope(text: str | bytes, topic: str) -> Envelope:
    """Parse wire text received on ``topic``; raises WireError (one line) when malformed. A MAC
    in the text is not checked here (:func:`decode_envelope_mac`)."""
    return decode_envelope_mac(text, topic)[0]


def decode_envelope_mac(text: str | bytes, topic: str) -> tuple[Envelope, str | None]:
    """:func:`decode_envelope` and the MAC the text carries (None when it has none), for the
    receiver to verify (msgs_json/auth.py RunAuth.verify)."""
    try:
        w = _dec.decode(text)
    except msgspec.DecodeError as exc:
        raise WireError(f"{topic}: bad envelope: {exc}") from None
    if w.t_ns < 0 or w.seq < 0 or not w.src:
        raise WireError(f"{topic}: bad envelope: t_ns/seq must be >= 0 and src non-empty")
    if (w.body is None) == (w.b64 is None):
        raise WireError(f"{topic}: bad envelope: exactly one of 'body' and 'b64' must be present")
    if w.b64 is not None:
        try:
            data: str | bytes = base64.b64decode(w.b64, validate=True)
        except (binascii.Error, ValueError):
            raise WireError(f"{topic}: bad envelope: 'b64' is not valid base64") from None
    else:
        data = w.body  # type: ignore[assignment]
    return Envelope(t_ns=w.t_ns, source=w.src, seq=w.seq, topic=topic, data=data), w.mac


_CDR_LE = b"\x00\x01\x00\x00"  # CDR little-endian encapsulation header
_U32 = struct.Struct("<I")


def string_cdr(text: str) -> bytes:
    """CDR (little endian) of std_msgs/msg/String(data=text), as rclpy serializes it."""
    b = text.encode("utf-8")
    return b"".join((_CDR_LE, _U32.pack(len(b) + 1), b, b"\x00"))


def string_from_cdr(cdr: bytes | memoryview) -> str:
    """Inverse of :func:`string_cdr` (little- or big-endian encapsulation); ValueError (one line)
    when ``cdr`` is not a std_msgs/String's CDR (UnicodeDecodeError is a ValueError)."""
    cdr = bytes(cdr)
    if len(cdr) < 9 or cdr[0] != 0 or cdr[1] not in (0, 1):
        raise ValueError("not a CDR std_msgs/String")
    n = struct.unpack("<I" if cdr[1] == 1 else ">I", cdr[4:8])[0]
    if n < 1 or 8 + n > len(cdr) or cdr[8 + n - 1] != 0:
        raise ValueError("CDR std_msgs/String length out of range")
    return cdr[8:8 + n - 1].decode("utf-8")


def without_mac(text: str, mac: str | None) -> str | None:
    """``text`` without its ``"mac"`` field when it ends with ``,"mac":"<mac>"}``, the field last as
    :func:`encode_envelope` writes it: ``without_mac(encode_envelope(env, mac), mac) ==
    encode_envelope(env)``. None when the text has no such tail (the caller encodes the decoded
    envelope again)."""
    if mac is None:
        return None
    tail = f',"mac":"{mac}"}}'
    if not text.endswith(tail) or len(text) <= len(tail):
        return None
    return text[:-len(tail)] + "}"
