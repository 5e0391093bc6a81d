"""The vehicle's parameters: a named, typed view onto its configuration dataclasses.

Each parameter binds a PX4-style name to one field of VehicleConfig ("section.field"), so defaults live in
one place (the config dataclasses and the airframe file) and a PARAM_SET lands directly in the config the
physics and controllers read. Files use QGroundControl's parameter format (tab separated:
`sysid compid name value type`), so a file saved here loads in QGC and back.
"""

from __future__ import annotations

import dataclasses
import math
import struct
from dataclasses import dataclass
from pathlib import Path

# MAV_PARAM_TYPE values used here
INT32 = 6
REAL32 = 9


class ParameterError(ValueError):
    """A parameter name, value or file that cannot be used (the message says which and why)."""


@dataclass(frozen=True)
class ParamSpec:
    name: str  # at most 16 characters (MAVLink param_id)
    path: str  # "section.field" in VehicleConfig
    type: int  # INT32 or REAL32
    minimum: float
    maximum: float
    description: str


def encode_value(value: float, param_type: int) -> float:
    """The float to put in PARAM_VALUE.param_value: INT32 travels bytewise (PX4's PARAM_ENCODE_BYTEWISE)."""
    if param_type == INT32:
        return struct.unpack("<f", struct.pack("<i", int(value)))[0]
    return float(value)


def decode_value(raw: float, param_type: int) -> float:
    """Inverse of encode_value for a PARAM_SET's param_value."""
    if param_type == INT32:
        return float(struct.unpack("<i", struct.pack("<f", raw))[0])
    return float(raw)


class ParameterTable:
    """Ordered parameters over a config object; index order is the table's order."""

    def __init__(self, specs: list[ParamSpec], config) -> None:
        names = [s.name for s in specs]
        if len(set(names)) != len(names):
            raise ParameterError("duplicate parameter names in the table")
        for spec in specs:
            if len(spec.name) > 16:
                raise ParameterError(f"parameter name {spec.name!r} is longer than 16 characters")
        self.specs = specs
        self.by_name = {s.name: i for i, s in enumerate(specs)}
        self.config = config
        for spec in specs:  # fail at start-up, not on the first PARAM_REQUEST, if a path is wrong
            self.get(spec.name)

    def __len__(self) -> int:
        return len(self.specs)

    def spec(self, name_or_index: str | int) -> ParamSpec:
        if isinstance(name_or_index, int):
            if not 0 <= name_or_index < len(self.specs):
                raise ParameterError(f"parameter index {name_or_index} out of range 0..{len(self.specs) - 1}")
            return self.specs[name_or_index]
        if name_or_index not in self.by_name:
            raise ParameterError(f"unknown parameter {name_or_index!r}")
        return self.specs[self.by_name[name_or_index]]

    def index(self, name: str) -> int:
        return self.by_name[self.spec(name).name]

    def get(self, name: str) -> float:
        section, field = self.spec(name).path.split(".")
        return float(getattr(getattr(self.config, section), field))

    def set(self, name: str, value: float) -> float:
        """Validate and store; returns the stored value. Raises ParameterError (and changes nothing)."""
        spec = self.spec(name)
        if math.isnan(value) or (math.isinf(value) and value != spec.maximum):  # inf only where it is the maximum
            raise ParameterError(f"{name}: value must be finite, got {value}")
        if spec.type == INT32:
            if value != int(value):
                raise ParameterError(f"{name}: integer parameter, got {value}")
            value = int(value)
        if not spec.minimum <= value <= spec.maximum:
            raise ParameterError(f"{name}: {value} outside [{spec.minimum}, {spec.maximum}]")
        section_name, field = spec.path.split(".")
        section = getattr(self.config, section_name)
        try:
            updated = dataclasses.replace(section, **{field: value})
        except ValueError as exc:  # the section's own validation (e.g. a limit that must stay positive)
            raise ParameterError(f"{name}: {exc}") from exc
        setattr(self.config, section_name, updated)
        return float(value)

    # ----- files
    def save(self, path: str | Path, sysid: int = 1, compid: int = 1) -> None:
        lines = ["# Onboard parameters for buoy-inspection sitl_quad", "#", "# Stack: sitl_quad", "#"]
        lines.append("# Vehicle-Id Component-Id Name Value Type")
        for spec in self.specs:
            value = self.get(spec.name)
            text = str(int(value)) if spec.type == INT32 else repr(float(value))
            lines.append(f"{sysid}\t{compid}\t{spec.name}\t{text}\t{spec.type}")
        Path(path).write_text("\n".join(lines) + "\n")

    def load(self, path: str | Path) -> int:
        """Apply a parameter file; all lines are checked before any is applied. Returns how many were set."""
        try:
            text = Path(path).read_text()
        except OSError as exc:
            raise ParameterError(f"cannot read parameter file {path}: {exc.strerror}") from exc
        pending: list[tuple[str, float]] = []
        for number, line in enumerate(text.splitlines(), 1):
            if not line.strip() or line.lstrip().startswith("#"):
                continue
            fields = line.split()
            if len(fields) not in (2, 5):
                raise ParameterError(f"{path}:{number}: expected 'SYSID COMPID NAME VALUE TYPE' or 'NAME VALUE'")
            name, raw = (fields[2], fields[3]) if len(fields) == 5 else (fields[0], fields[1])
            try:
                value = float(raw)
            except ValueError as exc:
                raise ParameterError(f"{path}:{number}: {name}: {raw!r} is not a number") from exc
            self.spec(name)
            pending.append((name, value))
        sections = {s.path.split(".")[0] for s in self.specs}
        snapshot = {name: getattr(self.config, name) for name in sections}  # sections are immutable values
        try:
            for name, value in pending:
                self.set(name, value)
        except ParameterError:
            for name, section in snapshot.items():  # all or nothing
                setattr(self.config, name, section)
            raise
        return len(pending)
