"""Flight-software operations of one satellite: modes and their fault rules (modes.py), mode notices
to the neighbours (notice.py), the per-satellite state the satellite keeps (controller.py)."""
