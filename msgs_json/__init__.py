"""msgs_json package."""
