"""The burst's on/off split of a lamp's spot brightness (gcs.domain.light_reading), on the levels a flown burst
measured: dark frames at two levels (sea behind the spot, and a brighter whitecap or sky), the lamp above both."""

from __future__ import annotations

import numpy as np

from gcs.domain.light_reading import LIT_LEVEL, LightSpot, lit_frames, read_light

# Fl G 4s over 9 s at 10 Hz, as a demo flight measured it (B9): the lamp at 0.93-0.97; the sea behind the spot at
# 0.37-0.56 and, for a stretch, a whitecap at 0.69-0.78 (above MIN_LAMP_LEVEL: Otsu's split fell between the two
# dark levels and read the whitecap as the lamp)
FLOWN = [
    *[0.37, 0.37, 0.96, 0.95, 0.95, 0.97, 0.97, *[0.39] * 35, 0.97, 0.96, 0.96, 0.94, 0.96, 0.54],
    *[0.70, 0.71, 0.75, 0.74, 0.76, 0.78, 0.73] * 3,
    *[*[0.5] * 12, 0.69, 0.96, 0.96, 0.96, 0.96, 0.93, 0.69, 0.63, 0.68],
]


def spots(levels: list[float]) -> list[LightSpot]:
    return [LightSpot((0.0, 0.0), level, "G") for level in levels]


def test_a_bright_dark_level_between_the_sea_and_the_lamp_is_read_dark():
    on = lit_frames(spots(FLOWN))
    assert on == [level >= LIT_LEVEL for level in FLOWN]
    times = list(np.arange(len(FLOWN)) * 0.1)
    light = read_light(times, spots(FLOWN))
    assert (light.rhythm, light.pattern, light.colour) == ("flashing", ".", "G")
    assert abs(light.period_s - 4.0) < 0.15


def test_a_burst_with_one_level_believes_each_frames_own_reading():
    steady = [0.95, 0.96, 0.94, 0.95]
    assert lit_frames(spots(steady)) == [True] * 4
    assert lit_frames(spots([0.4, 0.45, 0.42, 0.5])) == [False] * 4
