"""sat_node package."""
