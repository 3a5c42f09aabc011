"""dtn_router package."""
