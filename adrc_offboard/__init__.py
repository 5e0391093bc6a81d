"""adrc_offboard package."""
