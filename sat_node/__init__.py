"""One satellite's flight software (pure core; no rclpy here): slew model, value/belief, scheduler."""

import importlib

# name -> submodule, imported on first use (PEP 562): importing one light part (the BPv7 codec, the
# convergence layers) does not load numba through sat_node.value
_LAZY = {"SlewModel": "acs", "SlewModelError": "acs", "slew_angle_deg": "acs", "Belief": "value",
         "KnownObservation": "value", "belief_sigma": "value", "prior_state": "value", "true_value": "value"}


def __getattr__(name: str):
    if name in _LAZY:
        return getattr(importlib.import_module(f"sat_node.{_LAZY[name]}"), name)
    raise AttributeError(f"module 'sat_node' has no attribute {name!r}")


__all__ = [
    "Belief",
    "KnownObservation",
    "SlewModel",
    "SlewModelError",
    "belief_sigma",
    "prior_state",
    "slew_angle_deg",
    "true_value",
]
