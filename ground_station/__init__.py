"""ground_station package."""
