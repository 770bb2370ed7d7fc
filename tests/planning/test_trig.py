"""The joint angles' sine and cosine: accurate, and the same bits in numpy and compiled."""

from __future__ import annotations

import numpy as np
from numba import njit

from planning.compiled.trig import REDUCED_UP_TO, sincos, sincos_array

_compiled = njit(sincos)


def _angles() -> np.ndarray:
    rng = np.random.default_rng(3)
    quadrants = np.arange(-40, 41) * (np.pi / 4)  # where the reduction changes quadrant
    return np.concatenate(
        [
            rng.uniform(-4 * np.pi, 4 * np.pi, 20_000),
            quadrants,
            np.nextafter(quadrants, np.inf),
            np.nextafter(quadrants, -np.inf),
            [0.0, -0.0, 1e-300, 1e-9, -1e-9, REDUCED_UP_TO, -REDUCED_UP_TO],
        ]
    )


def test_sine_and_cosine_are_within_two_ulp_of_the_library() -> None:
    x = _angles()
    s, c = sincos(x)
    for mine, truth in ((s, np.sin(x)), (c, np.cos(x))):
        # absolute error: what the kinematics feel (a unit of the last place of 1)
        assert np.max(np.abs(mine - truth)) <= 2 * np.spacing(1.0)
        big = np.abs(truth) > 1e-3
        ulps = np.abs(mine - truth)[big] / np.spacing(np.abs(truth[big]))
        assert ulps.max() <= 2.0


def test_numpy_and_compiled_give_the_same_bits() -> None:
    x = _angles()
    s, c = sincos(x)
    for k in range(0, len(x), 37):
        cs, cc = _compiled(float(x[k]))
        assert cs == s[k] and cc == c[k], x[k]


def test_beyond_the_reduced_range_the_library_answers() -> None:
    x = np.array([0.5, 3 * REDUCED_UP_TO, -7e6])
    s, c = sincos_array(x.copy())
    np.testing.assert_array_equal(s[1:], np.sin(x[1:]))
    np.testing.assert_array_equal(c[1:], np.cos(x[1:]))
    assert s[0] == sincos(0.5)[0]


def test_single_precision_angles_are_reduced_in_double() -> None:
    x = np.linspace(-2 * np.pi, 2 * np.pi, 1001)
    s, c = sincos_array(x.astype(np.float32))
    assert s.dtype == np.float32 and c.dtype == np.float32
    ref_s, ref_c = sincos(x.astype(np.float32).astype(np.float64))
    np.testing.assert_array_equal(s, ref_s.astype(np.float32))
    np.testing.assert_array_equal(c, ref_c.astype(np.float32))
