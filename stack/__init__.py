"""The whole stack on one machine, outside the ground station: simulated vehicles (sitl_quad), their offboard
controllers (adrc_offboard) and the service (gcs serve) as supervised children, and the paper's demo flown
through the service's REST API.

- `cli`: `buoy-gcs`, the ground station's command line with `up` added
- `options`: what `up` is asked to start, and the loops each controller flies with
- `children`: the children's command lines and environments, in start order
- `ports`: the vehicles' UDP and the service's HTTP ports, checked before any child starts (a busy default moved up)
- `supervisor`: start in order, watch, restart a crashed child, stop cleanly (a failure shows its log's reason)
- `up`: one or two lives of the stack (`--compare`), the demo flown in each
- `demo`: the reference scenario in the paper's weather, flown and reported
- `service_api`: small stdlib HTTP helpers for the service's API
- `sim_speed`: `--real-time` / `--watch-speed N`, the vehicles' SIM_SPEEDUP set over MAVLink once the demo has flown

The ground station never imports this package (lint-imports: layers); this package drives the vehicle and the
controller as processes, by their command lines.
"""
