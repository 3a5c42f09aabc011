"""A scenario as plain data with every field that has a value: what the world key and the
provenance's round-trip check compare.

Not msgspec.to_builtins, which leaves out a field of an ``omit_defaults`` struct (a constellation
group, bringup/scenario/groups.py) only when it holds the very default object: a scenario unpickled,
or read from a file that spells a default out, would look different from the same scenario made in
memory. Checked by tests/unit/test_world.py (test_key_does_not_depend_on_how_the_scenario_was_made).
"""

from __future__ import annotations

import msgspec

__all__ = ["canonical_data"]


def canonical_data(obj):
    """``obj`` (a scenario or any part of it) as dicts, lists and scalars, every field with a value."""
    if isinstance(obj, msgspec.Struct):
        return {f: canonical_data(v) for f in obj.__struct_fields__ if (v := getattr(obj, f)) is not msgspec.UNSET}
    if isinstance(obj, (list, tuple)):
        return [canonical_data(v) for v in obj]
    if isinstance(obj, dict):
        return {k: canonical_data(v) for k, v in obj.items()}
    return obj
