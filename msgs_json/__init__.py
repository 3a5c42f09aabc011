"""msgs_json: the message contracts (DESIGN.md section 4).

Front door: schemas (one msgspec Struct per message type), topic names and their schemas,
validating encode/decode, and the lockstep envelope and its wire form.
"""

from msgs_json.codec import MessageError, decode, decode_as, encode, encode_bytes
from msgs_json.envelope import Emit, Envelope, Participant, StepResult
from msgs_json.schemas import *  # noqa: F403
from msgs_json.schemas import __all__ as _schemas_all
from msgs_json.topics import *  # noqa: F403
from msgs_json.topics import __all__ as _topics_all
from msgs_json.wire import WireError, decode_envelope, encode_envelope

__all__ = sorted(
    set(_schemas_all)
    | set(_topics_all)
    | {
        "MessageError", "decode", "decode_as", "encode", "encode_bytes",
        "Emit", "Envelope", "Participant", "StepResult",
        "WireError", "decode_envelope", "encode_envelope",
    }
)
