"""One satellite's flight software (pure core; no rclpy here): slew model, value/belief, scheduler."""

from sat_node.acs import SlewModel, SlewModelError, slew_angle_deg
from sat_node.value import Belief, KnownObservation, belief_sigma, prior_state, true_value

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
