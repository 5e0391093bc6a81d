"""The HTTP face of the ground station: the app, its routes, security, headers and the live feed."""
