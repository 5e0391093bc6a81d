"""Controller parameter sets as data: the JSON files in this folder, and how a channel spec becomes a channel.

A channel spec is a JSON object in one of three forms (b0 comes from the caller: 1 for a position channel
whose control is acceleration, 1/I for an attitude channel whose control is torque):

- nonlinear ADRC, designer's form: {"omega_c", "omega_o", "delta", "r1", ...}: `adrc.bandwidth_parameters`;
- nonlinear ADRC, the paper's symbols: {"beta1", "beta2", "beta3", "delta", "r1", "h1", "c", ...};
- linear ADRC: {"kind": "linear", "omega_o", "omega_c", ...}.

Every form accepts optional "r0", "h0" (tracking differentiator), "alpha1", "alpha2" (nonlinear only) and
"u_max" (symmetric limit) or "u_min" / "u_max". Unknown keys are refused: a typo in a data file must not
silently fall back to a default.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from importlib import resources
from pathlib import Path
from typing import Any

from adrc_offboard.adrc import AdrcChannel, AdrcChannelParameters, AdrcParameterError, bandwidth_parameters
from adrc_offboard.ladrc import LinearAdrcChannel, LinearAdrcParameters

ChannelParameters = AdrcChannelParameters | LinearAdrcParameters
Channel = AdrcChannel | LinearAdrcChannel

_COMMON = {"r0", "h0", "u_min", "u_max"}
_FORMS = {
    "bandwidth": {"omega_c", "omega_o", "delta", "r1", "alpha1", "alpha2", "damping"} | _COMMON,
    "paper": {"beta1", "beta2", "beta3", "delta", "r1", "h1", "c", "alpha1", "alpha2"} | _COMMON,
    "linear": {"kind", "omega_o", "omega_c"} | _COMMON,
}


def load_gains(source: str | Path) -> dict[str, Any]:
    """A parameter file as a dict: a bare name ("attitude_adrc") is one of this folder's files, anything
    with a slash or a .json suffix a path."""
    try:
        if isinstance(source, Path) or "/" in source or source.endswith(".json"):
            text = Path(source).read_text()
        else:
            text = resources.files(__package__).joinpath(f"{source}.json").read_text()
        data = json.loads(text)
    except (OSError, json.JSONDecodeError) as exc:
        raise AdrcParameterError(f"cannot read gains {source!s}: {exc}") from exc
    if not isinstance(data, dict):
        raise AdrcParameterError(f"gains {source!s} must hold a JSON object")
    return data


def channel_parameters(spec: Mapping[str, Any], b0: float) -> ChannelParameters:
    """Parse one channel spec (see the module docstring) for input gain b0."""
    if not isinstance(spec, Mapping):
        raise AdrcParameterError(f"a channel spec must be a JSON object, got {spec!r}")
    form = "linear" if spec.get("kind") == "linear" else ("bandwidth" if "omega_o" in spec else "paper")
    if "kind" in spec and spec["kind"] not in ("linear", "nonlinear"):
        raise AdrcParameterError(f"channel kind must be 'linear' or 'nonlinear', got {spec['kind']!r}")
    unknown = set(spec) - _FORMS[form] - {"kind"}
    if unknown:
        raise AdrcParameterError(f"unknown keys {sorted(unknown)} in {form} channel spec {dict(spec)}")
    values = {k: v for k, v in spec.items() if k != "kind"}
    if "u_max" in values and "u_min" not in values:
        values["u_min"] = -values["u_max"]
    values.setdefault("u_min", -math.inf)
    values.setdefault("u_max", math.inf)
    try:
        if form == "linear":
            return LinearAdrcParameters(b0=b0, **values)
        if form == "bandwidth":
            return bandwidth_parameters(b0=b0, **values)
        return AdrcChannelParameters(b0=b0, **values)
    except TypeError as exc:  # a required key is missing
        raise AdrcParameterError(f"incomplete {form} channel spec {dict(spec)}: {exc}") from exc


def make_channel(parameters: ChannelParameters, h: float) -> Channel:
    """The channel for a parsed parameter set at sampling step h (validates it)."""
    if isinstance(parameters, LinearAdrcParameters):
        return LinearAdrcChannel(parameters, h)
    return AdrcChannel(parameters, h)
