"""The MAVLink parameter protocol, client side, for reading: parameters by name over the link manager.

As MAVSDK's param plugin does: PARAM_REQUEST_READ with the name (param_index -1) to the vehicle, wait for the
PARAM_VALUE that names it, send again if none came. Several names are asked for together: every try sends a
request for each name still unanswered, and the answers are taken in whatever order they come. A vehicle stays
silent for a name it does not know (PX4, ArduPilot and our simulator alike), so an unknown name and a lost link
look the same: after the last try `ParameterError` names what did not answer.

PARAM_VALUE carries every value in a float. An integer parameter is either that float's four bytes
reinterpreted (PX4, MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE: INT32 4 arrives as 5.6e-45) or the integer
converted to a float (ArduPilot, PARAM_ENCODE_C_CAST); the autopilot flavour says which (`gcs.vehicle.autopilots`).
"""

from __future__ import annotations

import asyncio
import math
import struct
from collections.abc import Sequence
from typing import TYPE_CHECKING

from gcs.vehicle.autopilots import PARAM_ENCODE_BYTEWISE
from gcs.vehicle.errors import LinkError
from uavcore.mavlink import mavlink, param_id

if TYPE_CHECKING:
    from gcs.vehicle.link import LinkManager

PARAM_TRIES = 3  # as MAVSDK's param plugin
PARAM_ID_LENGTH = 16  # PARAM_REQUEST_READ.param_id: at most 16 characters
# The native type of each MAV_PARAM_TYPE that fits in param_value's four bytes (little-endian, as MAVLink).
# The 64-bit types do not fit: they travel only in the PARAM_EXT messages.
_BYTEWISE_FORMATS = {
    mavlink.MAV_PARAM_TYPE_UINT8: "<B",
    mavlink.MAV_PARAM_TYPE_INT8: "<b",
    mavlink.MAV_PARAM_TYPE_UINT16: "<H",
    mavlink.MAV_PARAM_TYPE_INT16: "<h",
    mavlink.MAV_PARAM_TYPE_UINT32: "<I",
    mavlink.MAV_PARAM_TYPE_INT32: "<i",
}


class ParameterError(LinkError):
    """Parameters the vehicle did not answer for (`names`): unknown to it, or every try was lost."""

    def __init__(self, names: Sequence[str], why: str) -> None:
        self.names = tuple(names)
        super().__init__(f"parameter {', '.join(self.names)}: {why}")


def decode_param_value(raw: float, param_type: int, encoding: int) -> float:
    """The value PARAM_VALUE.param_value `raw` stands for, given its MAV_PARAM_TYPE and the autopilot's encoding
    of integers (`gcs.vehicle.autopilots.PARAM_ENCODE_BYTEWISE` or `PARAM_ENCODE_C_CAST`). REAL32 is always the float.

    A bytewise integer whose four bytes form a float32 signalling NaN (INT32 0x7F800001-0x7FBFFFFF, or
    -8388607..-4194305) comes back with its quiet bit set: pymavlink hands the float over as a Python (double)
    float, which quiets it. No autopilot parameter we read holds such a value."""
    fmt = _BYTEWISE_FORMATS.get(param_type)
    if fmt is None:
        return float(raw)
    if encoding == PARAM_ENCODE_BYTEWISE:
        return float(struct.unpack_from(fmt, struct.pack("<f", raw))[0])
    return float(round(raw)) if math.isfinite(raw) else float(raw)


async def read_parameters(link: LinkManager, names: Sequence[str], timeout_s: float = 3.0) -> dict[str, float]:
    """{name: value} for each of `names`, read from the vehicle the link talks to. `timeout_s` (wall clock) is
    shared by PARAM_TRIES tries; raises ParameterError naming the parameters still unanswered after the last."""
    wanted = list(dict.fromkeys(names))  # each name once, in the caller's order
    malformed = [name for name in wanted if not (0 < len(name) <= PARAM_ID_LENGTH and name.isascii())]
    if malformed:
        raise ParameterError(malformed, f"a parameter name is 1 to {PARAM_ID_LENGTH} ASCII characters")
    values: dict[str, float] = {}
    loop = asyncio.get_running_loop()
    with link.subscribe({"PARAM_VALUE"}) as inbox:
        for _ in range(PARAM_TRIES):
            missing = [name for name in wanted if name not in values]
            if not missing:
                break
            for name in missing:
                link.send(link.encoder.param_request_read_encode(*link.target, name.encode("ascii"), -1))
            deadline = loop.time() + timeout_s / PARAM_TRIES
            while len(values) < len(wanted) and (remaining := deadline - loop.time()) > 0:
                try:
                    async with asyncio.timeout(remaining):
                        message = await inbox.get()
                except TimeoutError:
                    break
                name = param_id(message)  # PARAM_VALUE has no target: another station's answer serves too
                if name in wanted:
                    values[name] = decode_param_value(
                        message.param_value, message.param_type, link.autopilot.param_encoding
                    )
    missing = [name for name in wanted if name not in values]
    if missing:
        raise ParameterError(
            missing, f"no PARAM_VALUE after {PARAM_TRIES} tries in {timeout_s:g} s ({link.connection})"
        )
    return {name: values[name] for name in names}
