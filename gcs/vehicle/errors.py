"""What a vehicle link raises (gcs.vehicle.link and the protocols it runs: gcs.vehicle.parameters, gcs.vehicle.ftp),
in a module of its own so those protocol modules need not import the link manager."""

from __future__ import annotations

from uavcore.mavlink import result_name


class LinkError(RuntimeError):
    """The vehicle did not answer or cannot be reached; the message says what was asked."""


class CommandTimeoutError(LinkError):
    pass


class CommandDeniedError(LinkError):
    """The vehicle answered a command with something other than ACCEPTED (`result` is the MAV_RESULT); `said`: the
    STATUSTEXTs it sent with its refusal, the real cause in its own words ("Arming denied: battery 0%, below 7%"),
    which lead the message: the MAV_RESULT alone tells an operator only that it said no."""

    def __init__(self, what: str, result: int, said: tuple[str, ...] = ()) -> None:
        self.result, self.said = result, said
        because = f": {'; '.join(said)}" if said else ""
        super().__init__(f"the vehicle refused to {what}{because} ({result_name('MAV_RESULT', result)})")
