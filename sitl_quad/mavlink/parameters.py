"""The PARAM protocol: list, read by name or index, set; INT32 values travel bytewise (PX4 style)."""

from __future__ import annotations

import logging

from sitl_quad.params import ParameterError, ParameterTable, decode_value, encode_value
from uavcore.mavlink import mavlink, param_id

log = logging.getLogger(__name__)
LIST_BURST = 25  # PARAM_VALUEs sent per loop pass while streaming the list: gentle on slow links


class Parameters:
    def __init__(self, table: ParameterTable, send, on_change) -> None:
        self.table = table
        self.send = send  # callable(msg, peer=None)
        self.on_change = on_change  # callable(section_name): the vehicle rebuilds what depends on it
        self._pending: list[tuple[object, int]] = []  # (peer, index) still to send for a list request

    def handlers(self) -> dict:
        return {
            "PARAM_REQUEST_LIST": self.request_list,
            "PARAM_REQUEST_READ": self.request_read,
            "PARAM_SET": self.param_set,
        }

    def value_message(self, index: int):
        spec = self.table.spec(index)
        raw = encode_value(self.table.get(spec.name), spec.type)
        return mavlink.MAVLink_param_value_message(spec.name.encode(), raw, spec.type, len(self.table), index)

    def request_list(self, peer, msg) -> None:
        self._pending = [(p, i) for p, i in self._pending if p is not peer]
        self._pending.extend((peer, i) for i in range(len(self.table)))

    def poll(self) -> None:
        """Send the next burst of a pending list (called on every loop pass)."""
        burst, self._pending = self._pending[:LIST_BURST], self._pending[LIST_BURST:]
        for peer, index in burst:
            self.send(self.value_message(index), peer)

    def request_read(self, peer, msg) -> None:
        try:
            if msg.param_index >= 0:
                index = msg.param_index
                self.table.spec(index)
            else:
                index = self.table.index(param_id(msg))
        except ParameterError as exc:
            log.info("PARAM_REQUEST_READ: %s", exc)
            return  # PX4 stays silent for an unknown parameter; the client times out
        self.send(self.value_message(index), peer)

    def param_set(self, peer, msg) -> None:
        name = param_id(msg)
        try:
            spec = self.table.spec(name)
        except ParameterError as exc:
            log.info("PARAM_SET: %s", exc)
            return
        value = decode_value(msg.param_value, spec.type)  # non-finite REAL32 values are refused by set()
        try:
            self.table.set(name, value)
            self.on_change(spec.path.split(".")[0])
        except ParameterError as exc:
            log.info("PARAM_SET refused: %s", exc)  # answered below with the unchanged value
        self.send(self.value_message(self.table.index(name)))  # to everyone: all GCSs learn the change
