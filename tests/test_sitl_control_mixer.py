"""The mixer inverts eq. (3) and saturates with roll/pitch, then thrust, then yaw priority."""

from __future__ import annotations

import numpy as np
import pytest

from sitl_quad.rotors import Mixer, rotor_wrench
from uavcore.airframe import Airframe, ModelParameterError

AIRFRAME = Airframe.table2()
PARAMS = AIRFRAME.as_array()


def wrench(omega):
    return np.array(rotor_wrench(np.asarray(omega, dtype=float), PARAMS))


@pytest.mark.parametrize(
    ("thrust", "torque"),
    [
        (12.75, (0.0, 0.0, 0.0)),
        (12.75, (0.5, -0.3, 0.05)),
        (20.0, (-1.0, 1.0, -0.03)),
        (5.0, (0.2, 0.2, 0.02)),
    ],
)
def test_mixer_inverts_eq3_when_within_limits(thrust, torque):
    mixer = Mixer(AIRFRAME)
    omega = mixer.rotor_commands(thrust, torque)
    assert not mixer.saturated
    np.testing.assert_allclose(wrench(omega), [thrust, *torque], rtol=1e-9, atol=1e-12)


def test_hover_is_four_equal_hover_speeds():
    omega = Mixer(AIRFRAME).rotor_commands(AIRFRAME.mass * AIRFRAME.g, np.zeros(3))
    np.testing.assert_allclose(omega, AIRFRAME.hover_rotor_speed)


def test_yaw_gives_way_first():
    mixer = Mixer(AIRFRAME)
    thrust, roll = AIRFRAME.mass * AIRFRAME.g, 1.0
    omega = mixer.rotor_commands(thrust, (roll, 0.0, 5.0))  # far more yaw than the rotors can give
    assert mixer.saturated and mixer.saturated_steps == 1
    assert np.all(omega <= AIRFRAME.rotor_speed_max + 1e-9) and np.all(omega >= 0.0)
    achieved = wrench(omega)
    assert achieved[0] == pytest.approx(thrust) and achieved[1] == pytest.approx(roll)
    assert 0.0 < achieved[3] < 5.0


def test_roll_and_pitch_kept_before_thrust():
    mixer = Mixer(AIRFRAME)
    omega = mixer.rotor_commands(AIRFRAME.max_thrust_n, (0.0, 2.0, 0.0))  # full thrust leaves no room
    assert mixer.saturated
    achieved = wrench(omega)
    assert achieved[2] == pytest.approx(2.0)
    assert achieved[0] < AIRFRAME.max_thrust_n
    huge = mixer.rotor_commands(AIRFRAME.mass * AIRFRAME.g, (100.0, 100.0, 0.0))  # beyond any rotor range
    achieved = wrench(huge)
    assert achieved[1] == pytest.approx(achieved[2]) and achieved[1] > 0  # direction kept, magnitude scaled
    assert np.all(huge <= AIRFRAME.rotor_speed_max + 1e-9)


def test_mixer_rejects_non_finite_input():
    with pytest.raises(ModelParameterError):
        Mixer(AIRFRAME).rotor_commands(float("nan"), (0.0, 0.0, 0.0))
