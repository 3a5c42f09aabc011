"""Authenticated run traffic: a MAC under the run's key on every message of a run.

Every process of a ROS run shares one secret, the run key (32 random bytes made per run by the
launcher, bringup/engine/keys.py). Everything a run sends on DDS carries a MAC under it, and a
receiver acts on, counts or records only what verifies:

* **envelopes** (msgs_json/wire.py, every data topic): the wire JSON gets a ``"mac"`` field, the
  keyed BLAKE2b (RFC 7693 keyed mode, 16-byte tag) of the envelope's fields - topic, t_ns, source,
  seq and the payload (text or bytes, with its kind) - each length-prefixed or fixed-form, so no two
  envelopes have the same MAC input. The topic is the one the receiver subscribed to, so an envelope
  moved to another topic fails; another run's envelope fails (another key); a copy of one of this
  run's envelopes is the same (source, seq) again, which every receiver drops as a duplicate
  (bringup/engine/lockstep.py TopicInbox).
* **lockstep messages** (/sim/step, /sim/ack, /_lockstep/resend: JSON objects): the text gets a
  ``,"mac":"<32 hex>"}`` tail, the MAC of the topic and the text before it (:meth:`RunAuth.seal` /
  :meth:`RunAuth.open`); ``open`` gives back the text without the tail, which is the message's
  ordinary JSON (decoded as before).

Rejections carry a reason (:class:`AuthError`): ``malformed`` (not a message at all),
``unauthenticated`` (no MAC) or ``bad_mac`` (a MAC that does not verify: wrong key, tampered
byte, another run's, another topic's). Tags are compared in constant time (hmac.compare_digest).

Cost: one BLAKE2b of the message from a keyed state made once (``copy``), ~0.5-0.8 us per
envelope on the project's machines (bench/bench_lockstep.py prints the per-message figure).

Why our own layer: DDS Security (SROS2) would be the ROS way, but the FastDDS 2.14 in the Jazzy wheels
is built without its security plugins (README "Authenticated run traffic";
tests/ros/test_dds_security_absent.py keeps that fact checked).

Oracle: tests/unit/test_auth.py - a flipped byte anywhere (field, payload, tag), a wrong key,
another run's envelope, another topic, a missing tag, and a text tail that is not ours are each
rejected with their reason; round trips of random envelopes (text with escapes and non-ASCII,
bytes) verify; the MAC input of two different envelopes differs (length prefixes).
"""

from __future__ import annotations

import hashlib
import hmac

from msgs_json.envelope import Envelope

__all__ = ["AUTH_REASONS", "MAC_HEX", "AuthError", "RunAuth"]

AUTH_REASONS = ("malformed", "unauthenticated", "bad_mac")
_TAG = 16  # bytes of the MAC (128 bits)
MAC_HEX = 2 * _TAG
_TAIL_HEAD = ',"mac":"'
_TAIL_LEN = len(_TAIL_HEAD) + MAC_HEX + 2  # ,"mac":"<hex>"}


class AuthError(ValueError):
    """A message that is not authenticated under the run's key; ``reason`` is one of
    :data:`AUTH_REASONS`, the message says what and where on one line."""

    def __init__(self, reason: str, message: str):
        super().__init__(message)
        self.reason = reason


class RunAuth:
    """MACs under one run key (see the module docstring)."""

    def __init__(self, key: bytes):
        if not isinstance(key, bytes) or len(key) < 16:
            raise ValueError("run key: bytes of length >= 16 needed")
        # keyed states made once; each MAC copies one (saves the key block's compression)
        self._env = hashlib.blake2b(key=key, digest_size=_TAG, person=b"agile-dtn-env")
        self._txt = hashlib.blake2b(key=key, digest_size=_TAG, person=b"agile-dtn-txt")

    # -- envelopes ----------------------------------------------------------------------------------
    def mac(self, env: Envelope) -> str:
        """The MAC (hex) of ``env``: topic, t_ns, source, seq, payload kind and payload."""
        h = self._env.copy()
        d = env.data
        if type(d) is bytes:
            kind, raw = b"b", d
        else:
            kind, raw = b"s", d.encode("utf-8", "surrogatepass")
        t = env.topic.encode("utf-8", "surrogatepass")
        s = env.source.encode("utf-8", "surrogatepass")
        h.update(b"%d:%b%d:%b %d %d %b" % (len(t), t, len(s), s, env.t_ns, env.seq, kind))
        h.update(raw)
        return h.hexdigest()

    def verify(self, env: Envelope, mac: str | None) -> None:
        """Raise AuthError unless ``mac`` is ``env``'s MAC."""
        if mac is None:
            raise AuthError("unauthenticated", f"{env.topic}: envelope from {env.source!r} has no MAC")
        if not hmac.compare_digest(self.mac(env), mac if mac.isascii() else ""):
            raise AuthError("bad_mac", f"{env.topic}: envelope from {env.source!r} seq {env.seq}: MAC does not verify")

    # -- lockstep messages (JSON object texts) --------------------------------------------------------
    def _text_mac(self, topic: str, body: bytes) -> str:
        h = self._txt.copy()
        t = topic.encode("utf-8", "surrogatepass")
        h.update(b"%d:%b" % (len(t), t))
        h.update(body)
        return h.hexdigest()

    def seal(self, topic: str, text: str) -> str:
        """``text`` (a non-empty JSON object) with the MAC tail: ``{..., "mac":"<hex>"}``."""
        if len(text) < 3 or not text.endswith("}"):
            raise ValueError(f"{topic}: only a non-empty JSON object text can be sealed")
        return text[:-1] + _TAIL_HEAD + self._text_mac(topic, text.encode("utf-8", "surrogatepass")) + '"}'

    def open(self, topic: str, text: str | bytes) -> str:
        """The text ``seal`` was given, after checking its MAC; AuthError otherwise."""
        if isinstance(text, bytes):
            try:
                text = text.decode("utf-8")
            except UnicodeDecodeError:
                raise AuthError("malformed", f"{topic}: not UTF-8 text") from None
        cut = len(text) - _TAIL_LEN
        if cut < 2 or not text.endswith('"}') or not text.startswith(_TAIL_HEAD, cut):
            raise AuthError("unauthenticated", f"{topic}: message has no MAC")
        mac = text[cut + len(_TAIL_HEAD):-2]
        body = text[:cut] + "}"
        raw = body.encode("utf-8", "surrogatepass")
        if not (mac.isascii() and hmac.compare_digest(self._text_mac(topic, raw), mac)):
            raise AuthError("bad_mac", f"{topic}: MAC does not verify")
        return body
