"""uavcore.rotation's matrix form against its vector form."""

import numpy as np
import pytest

from uavcore.rotation import matrix_from_quat, quat_from_euler, rotate


@pytest.mark.parametrize("euler", [(0.0, 0.0, 0.0), (0.3, -0.4, 2.0), (-1.2, 0.9, -3.0)])
def test_the_matrix_rotates_as_rotate_does_and_ignores_the_quaternions_scale(euler):
    q = quat_from_euler(*euler)
    vectors = np.array([[1.0, 2.0, 3.0], [0.0, 0.0, 1.0], [-4.0, 0.5, 0.0]])
    expected = np.array([rotate(q, v) for v in vectors])
    assert np.allclose(vectors @ matrix_from_quat(q).T, expected)
    assert np.allclose(matrix_from_quat(3.0 * q), matrix_from_quat(q))
