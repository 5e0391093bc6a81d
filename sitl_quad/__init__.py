"""sitl_quad package."""
