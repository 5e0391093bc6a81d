"""What a vehicle link raises (gcs.vehicle.link and the protocols it runs: gcs.vehicle.parameters, gcs.vehicle.ftp),
in a module of its own so those protocol modules need not import the link manager."""

from __future__ import annotations

from uavcore.mavlink import result_name


class LinkError(RuntimeError):
    """The vehicle did not answer or cannot be reached; the message says what was asked."""


class CommandTimeoutError(LinkError):
    pass


class CommandDeniedError(LinkError):
    """The vehicle answered a command with something other than ACCEPTED (`result` is the MAV_RESULT)."""

    def __init__(self, what: str, result: int) -> None:
        self.result = result
        super().__init__(f"the vehicle refused to {what} ({result_name('MAV_RESULT', result)})")
