"""gcs: the ground-control mission service (FastAPI + SQLite or PostgreSQL + MAVLink).

Read in this order:
- `settings` (every default, overridable from BUOY_GCS_* variables), `status` (MissionStatus),
  `schemas` (the REST contract, with the one TelemetrySample), `validation` (limits -> 422)
- `planning` (request -> plan -> mission items; uses planner), `tracking` (pure flight figures),
  `buoy_files` / `exports` (buoy files, track.geojson, QGC .plan and WPL 110)
- `storage` (the only package that knows SQL: SQLite or PostgreSQL, `open_storage`)
- `link` (the MAVLink link manager), `mission_protocol` (upload/download)
- `recorder` (a mission's samples and progress), `results` (a flown mission's figures),
  `lifecycle` (upload, arm, start, watch to the end), `missions` (the service: the facade the routes call)
- `report` (the mission report: PNG figures + index.html, cached per mission)
- `app` (create_app), `routes/*` (thin; `routes.deps` gives them the service), `views` (records -> documents),
  `cli` (`python -m gcs serve | report`); the whole stack as supervised children (`buoy-gcs up`) is the `stack`
  package, above this one: the ground station starts no vehicle
"""
