"""What the service shows of stored missions: API documents, the HTML/PNG report, fleet reports, exports."""
