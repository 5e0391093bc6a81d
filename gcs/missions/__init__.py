"""Missions: the service the routes call, each flight's lifecycle and recorder, fleets, energy, validation."""
