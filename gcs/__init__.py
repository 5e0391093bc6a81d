"""gcs: the ground-control mission service (FastAPI + SQLite or PostgreSQL + MAVLink).

Read in this order:
- `settings` (every default, overridable from BUOY_GCS_* variables), `status` (MissionStatus),
  `schemas` (the REST contract, with the one TelemetrySample), `validation` (limits -> 422)
- `planning` (request -> plan -> mission items; uses planner), `tracking_metrics` (pure: a flight's tracking
  figures in numbers), `buoy_files` / `exports` (buoy files, track.geojson, QGC .plan and WPL 110)
- `storage` (the only package that knows SQL: SQLite or PostgreSQL, `open_storage`)
- `link` (the MAVLink link manager; `link_errors` what it raises), `mission_protocol` (upload/download),
  `parameters` (read by name)
- `recorder` (a mission's samples and progress), `results` (a flown mission's figures),
  `lifecycle` (upload, arm, start, watch to the end), `missions` (the service: the facade the routes call)
- `report` (the mission report: PNG figures + index.html, cached per mission), `fleet_report`, `report_drawing`
  (what both draw with)
- `app` (create_app), `routes/*` (thin; `routes.deps` gives them the service), `views` (records -> documents),
  `cli` (`python -m gcs serve | report`); the whole stack as supervised children (`buoy-gcs up`) is the `stack`
  package, above this one: the ground station starts no vehicle
"""
