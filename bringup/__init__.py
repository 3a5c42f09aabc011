"""bringup package."""
