from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from calibration.pnp import robust_average
from gaide_core.errors import CalibrationError
from gaide_core.transforms import from_xyz_rpy, make_transform, transform_error


def test_robust_average_rejects_outliers(rng: np.random.Generator) -> None:
    truth = from_xyz_rpy([0.3, -0.1, 0.8], [0.4, -0.2, 1.0])
    poses = []
    for _ in range(12):
        noise = make_transform(
            Rotation.from_rotvec(rng.normal(0, np.radians(0.05), 3)).as_matrix(),
            rng.normal(0, 0.0003, 3),
        )
        poses.append(truth @ noise)
    poses[2] = truth @ from_xyz_rpy([0.02, 0, 0], [0, 0, 0])  # 2 cm off
    poses[7] = truth @ from_xyz_rpy([0, 0, 0], [0, np.radians(3.0), 0])  # flipped-ish tilt
    avg = robust_average(poses)
    assert [i for i, _ in avg.rejected] == [2, 7]
    assert "mm from the median" in dict(avg.rejected)[2]
    assert "deg from the mean" in dict(avg.rejected)[7]
    assert avg.used == tuple(i for i in range(12) if i not in (2, 7))
    dt, dr = transform_error(avg.T, truth)
    assert dt < 0.0003 and np.degrees(dr) < 0.05


def test_robust_average_keeps_identical_frames() -> None:
    """With no spread at all (MAD = 0) nothing within noise level is thrown away."""
    T = from_xyz_rpy([0.1, 0.2, 0.3], [0.1, 0.2, 0.3])
    wiggle = T @ from_xyz_rpy([0.0005, 0, 0], [0, 0, 0])
    avg = robust_average([T, T, T, wiggle])
    assert avg.rejected == () and len(avg.used) == 4


def test_robust_average_empty() -> None:
    with pytest.raises(CalibrationError, match="no poses"):
        robust_average([])
