"""The vocabulary every process of this project shares, at the bottom of the import graph.

It imports nothing of ours (an import-linter contract in pyproject.toml holds it to that):

- `geodesy`   WGS84 <-> local tangent plane (pymap3d), the default home;
- `state`     vehicle state, trajectory setpoint and attitude target types;
- `rotation`  quaternion/Euler helpers and the thrust-vector -> attitude map every position loop uses;
- `mission`   mission items as MISSION_ITEM_INT carries them, with MAV_CMD and MAV_FRAME as enums;
- `modes`     autopilot flight-mode encodings (PX4's main/sub custom modes);
- `control`   the controller contracts (Protocols) that the vehicle and the offboard process inject;
- `light_character` navigation-light characters (chart text, IALA timing) and reading one from camera frames;
- `buoy_world` the simulated world's buoys: IALA kind and look, charted and actual light, mooring swing, faults;
- `mavlink`   the one MAVLink codec: dialect, framing/parsing of datagrams, signing, system/component ids;
- `kernel_cache` `cached_kernel`, numba's cached njit for every kernel, invalidated by what the kernel imports.
"""
