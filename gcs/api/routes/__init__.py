"""HTTP and WebSocket routes: thin, each delegates to the mission service."""
