"""Sine and cosine of joint angles together, one definition for numpy and the kernels.

Why by hand: a revolute joint needs both the sine and the cosine of its angle, and libm's
``sin`` and ``cos``, which numba calls one at a time, cost about 10 ns each on the 2-core
machine: 122 ns of a 750 ns configuration check went to the six joints' twelve calls.
Neither numpy nor numba offers a fused ``sincos``. Here both share one range reduction and
two short polynomials, written with arithmetic only, so the same function runs on numpy
arrays (the reference kinematics) and, compiled, on scalars (the kernels), and gives the
same bits in both: IEEE multiplications and additions, no fused multiply-add in either, and
the quadrant chosen by exact products with 0 and 1 instead of branches.

Accuracy: within 2 ulp of the true values for |x| <= ``REDUCED_UP_TO`` (checked against
numpy in the tests); beyond that the callers use the library functions.
"""

from __future__ import annotations

from typing import Any

import numpy as np

# Range reduction by Cody and Waite: x - n pi/2 in two parts. PIO2_HI holds the first 33
# bits of pi/2, so n * PIO2_HI is exact for |n| < 2^20 and the first subtraction loses
# nothing; PIO2_LO is the rest of pi/2 to double precision.
INV_PIO2 = 6.36619772367581382433e-01
PIO2_HI = 1.57079632673412561417e00
PIO2_LO = 6.07710050650619224932e-11
REDUCED_UP_TO = 1.0e5  # rad: |n| < 2^17, far inside the exact range of n * PIO2_HI

# Minimax polynomials on [-pi/4, pi/4] (the classical double-precision coefficients):
# sin r = r + r^3 (S1 + S2 z + ... + S6 z^5), cos r = 1 - z / 2 + z^2 (C1 + ... + C6 z^5),
# z = r^2.
S1 = -1.66666666666666324348e-01
S2 = 8.33333333332248946124e-03
S3 = -1.98412698298579493134e-04
S4 = 2.75573137070700676789e-06
S5 = -2.50507602534068634195e-08
S6 = 1.58969099521155010221e-10
C1 = 4.16666666666666019037e-02
C2 = -1.38888888888741095749e-03
C3 = 2.48015872894767294178e-05
C4 = -2.75573143513906633035e-07
C5 = 2.08757232129817482790e-09
C6 = -1.13596475577881948265e-11


def sincos(x: Any) -> tuple[Any, Any]:
    """(sin x, cos x) for |x| <= REDUCED_UP_TO, a float or an array (elementwise)."""
    n = np.rint(x * INV_PIO2)
    r = (x - n * PIO2_HI) - n * PIO2_LO
    z = r * r
    sr = r + r * z * (S1 + z * (S2 + z * (S3 + z * (S4 + z * (S5 + z * S6)))))
    cr = (1.0 - 0.5 * z) + z * z * (C1 + z * (C2 + z * (C3 + z * (C4 + z * (C5 + z * C6)))))
    # Quadrant q = n mod 4: (sin, cos) = (sr, cr), (cr, -sr), (-sr, -cr), (-cr, sr).
    q = n - 4.0 * np.floor(n * 0.25)
    half = np.floor(q * 0.5)  # 1 for q in {2, 3}
    odd = q - 2.0 * half  # 1 for q in {1, 3}
    even = 1.0 - odd
    s = (sr * even + cr * odd) * (1.0 - 2.0 * half)
    c = (cr * even + sr * odd) * (1.0 - 2.0 * (half + odd - 2.0 * half * odd))
    return s, c


def sincos_array(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(sin x, cos x) elementwise, any x: :func:`sincos`, the library beyond its range.
    Computed in float64 (the reduction's constants need it), returned in x's dtype."""
    xd = np.asarray(x, np.float64)
    s, c = sincos(xd)
    far = np.abs(xd) > REDUCED_UP_TO
    if far.any():
        s[far], c[far] = np.sin(xd[far]), np.cos(xd[far])
    return s.astype(x.dtype, copy=False), c.astype(x.dtype, copy=False)
