"""gcs: the ground-control mission service (FastAPI + SQLite + MAVLink).

Read in this order:
- `settings` (plain data), `schemas` (the REST contract), `validation` (limits -> 422)
- `planning` (request -> plan -> mission items; uses planner), `tracking` (pure flight figures),
  `buoy_files` / `exports` (buoy files, track.geojson, QGC .plan and WPL 110)
- `storage` (the only module that knows SQL)
- `link` (the MAVLink link manager), `mission_protocol` (upload/download), `missions` (the lifecycle)
- `report` (the mission report: PNG figures + index.html, cached per mission)
- `app` (create_app), `routes/*` (thin), `views` (records -> documents), `cli` (`python -m gcs serve`)
"""
