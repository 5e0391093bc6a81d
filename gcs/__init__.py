"""gcs: the ground-control mission service (FastAPI + SQLite or PostgreSQL + MAVLink).

One sub-package per concern, each importing only those below it (import-linter's `gcs-layers` contract). Read
from the bottom up:
- `domain` the vocabulary, pure: `status` (MissionStatus), `schemas` (the REST contract, with the one
  TelemetrySample), `planning` (request -> plan -> mission items; uses planner), `records` (what a stored
  mission holds besides its plan: progress, results, the plan's energy and fleet sections, typed), the
  inspection's analysis of camera frames (`camera_geometry`, `paint_segmentation`, `buoy_detection`,
  `light_reading`, `inspection`), `buoy_files` (buoy lists from GeoJSON or CSV), `tracking_metrics` (a flight's
  tracking figures in numbers), `listing` (GET /missions' filters and cursors)
- `storage` (the only package that knows SQL: SQLite or PostgreSQL, `open_storage`; typed records in and out;
  the inspections' frames and records too)
- `vehicle` the MAVLink side, for any PX4 or ArduPilot: `connection` (udpin/udpout/tcp/serial), `link` (the link
  manager; `errors` what it raises), `autopilots`, `mission_protocol` (upload/download), `parameters`, `ftp`
  (files over MAVLink FTP), `camera` (the vehicle's camera: found, its lens read, its capture reports checked)
- `reports` what is shown of stored missions: `views` (records -> documents), `report` (PNG figures +
  index.html, cached per mission; its inspection section `inspection_report`), `fleet_report`, `drawing` (what
  both draw with), `exports` (track.geojson, QGC .plan and WPL 110, inspections CSV and GeoJSON), `track_display`
- `settings` (every default, overridable from BUOY_GCS_* variables)
- `missions` the work: `validation` (limits -> 422), `energy_planning`, `recorder` (a mission's samples and
  progress), `results` (a flown mission's figures), `inspector` (a sortie's camera frames to a verdict per buoy),
  `lifecycle` (upload, arm, start, watch to the end), the
  fleet (`fleet_vehicle`, `fleet_planning`, `fleet_missions`), `read_cache`, `ownership`, and `service`
  (MissionService: what the routes call)
- `api` the HTTP face: `app` (create_app), `routes/*` (thin; `routes.deps` gives them the service), `errors` (every
  error answer's one shape), `docs_pages` (/docs, /redoc offline), `security`, `http_headers`, `body_limit`,
  `live_feed` (/ws)
- `cli` (`python -m gcs serve | report`); the whole stack as supervised children (`buoy-gcs up`) is the `stack`
  package, above this one: the ground station starts no vehicle
"""
