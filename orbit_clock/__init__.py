"""orbit_clock package."""
