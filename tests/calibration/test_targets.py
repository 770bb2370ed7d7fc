from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from calibration.detect import detect, scan
from calibration.pnp import solve_pose
from calibration.targets import (
    Charuco,
    SingleTag,
    TagGrid,
    Target,
    parse_target,
    target_from_dict,
    to_dict,
)
from gaide_core.errors import CalibrationError
from gaide_core.transforms import make_transform, transform_error
from tests.calibration.synth import K, look_at_target, render

lengths = st.floats(0.005, 0.5, allow_nan=False)


def test_parse_cli_forms() -> None:
    assert parse_target("tag36h11:id=0,size=0.08") == SingleTag(0, 0.08)
    assert parse_target("grid:4x3,marker=0.04,sep=0.01,first=0") == TagGrid(4, 3, 0.04, 0.01, 0)
    assert parse_target("grid:2x2,marker=0.04,sep=0.01") == TagGrid(2, 2, 0.04, 0.01)
    assert parse_target("charuco:5x7,square=0.04,marker=0.03") == Charuco(5, 7, 0.04, 0.03)


@pytest.mark.parametrize(
    ("text", "why"),
    [
        ("tag36h11:id=0", "missing"),
        ("tag36h11:id=0,size=abc", "not a number"),
        ("tag36h11:id=0.5,size=0.1", "not an integer"),
        ("tag36h11:id=0,size=0.1,colour=1", "unknown field"),
        ("aruco:id=0,size=0.1", "unknown target kind"),
        ("grid:4by3,marker=0.04,sep=0.01", "not a size"),
        ("tag36h11 id=0", "no ':'"),
        ("tag36h11:id=600,size=0.1", "0..586"),
        ("tag36h11:id=1,size=-0.1", "positive length"),
        ("charuco:5x7,square=0.03,marker=0.04", "smaller than the square"),
    ],
)
def test_parse_rejects_with_reason(text: str, why: str) -> None:
    with pytest.raises(CalibrationError, match=why):
        parse_target(text)


targets = st.one_of(
    st.builds(SingleTag, st.integers(0, 586), lengths),
    st.builds(TagGrid, st.integers(1, 6), st.integers(1, 6), lengths, lengths, st.integers(0, 500)),
    st.builds(
        lambda sx, sy, sq, frac: Charuco(sx, sy, sq, sq * frac),
        st.integers(2, 9),
        st.integers(2, 9),
        lengths,
        st.floats(0.3, 0.95),
    ),
)


@given(targets)
def test_spec_and_dict_round_trip(target: Target) -> None:
    assert parse_target(target.spec()) == target
    assert target_from_dict(to_dict(target)) == target
    assert target_from_dict(target.spec()) == target


def test_target_from_dict_errors() -> None:
    with pytest.raises(CalibrationError, match="unknown"):
        target_from_dict({"type": "qr"})
    with pytest.raises(CalibrationError, match="lacks"):
        target_from_dict({"type": "tag36h11", "id": 3})


@pytest.mark.parametrize("px_per_m", [1000.0, 1234.5])
def test_texture_pixel_convention(px_per_m: float) -> None:
    """The tag's black square covers exactly the pixels whose centres lie inside it."""
    tag = SingleTag(0, 0.08)
    tex = tag.texture(px_per_m)
    h, w = tex.image.shape
    x_min, x_max, y_min, y_max = tex.extent
    assert (x_max - x_min) * px_per_m == pytest.approx(w)
    assert (y_max - y_min) * px_per_m == pytest.approx(h)
    xs = x_min + (np.arange(w) + 0.5) / px_per_m
    ys = y_max - (np.arange(h) + 0.5) / px_per_m
    inside = (np.abs(xs)[None, :] < 0.04) & (np.abs(ys)[:, None] < 0.04)
    assert np.all(tex.image[~inside] == 255)  # quiet zone is white
    # The one-cell black border of the tag: the outer ring of the square is all black.
    ring = inside & ~((np.abs(xs)[None, :] < 0.03) & (np.abs(ys)[:, None] < 0.03))
    assert np.all(tex.image[ring] == 0)


@pytest.mark.parametrize(
    "target",
    [SingleTag(17, 0.10), TagGrid(4, 3, 0.04, 0.01, first_id=20), Charuco(5, 7, 0.04, 0.03)],
    ids=["tag", "grid", "charuco"],
)
def test_rendered_texture_gives_back_its_pose(target: Target, rng: np.random.Generator) -> None:
    """Texture painted with the documented convention, seen by a pinhole camera at a known
    pose (cv2.warpPerspective), is detected and PnP returns that pose."""
    tex = target.texture(1000.0)
    centre = [(tex.extent[0] + tex.extent[1]) / 2, (tex.extent[2] + tex.extent[3]) / 2, 0.0]
    for rpy in ([0.35, -0.3, 0.2], [-0.25, 0.4, -1.0]):
        T = look_at_target([0.03, -0.02, 0.55], rpy, tex.viewed_from_z)
        T = T @ make_transform(None, -np.asarray(centre))
        image = render(target, T, rng)
        det = detect(image, target, K, None)
        assert det is not None
        assert set(det.ids) == set(target.ids)  # every tag of the target found
        assert det.foreign_ids == ()
        pose = solve_pose(det, target, K, None)
        dt, dr = transform_error(pose.T_cam_target, T)
        assert dt < 0.003 and np.degrees(dr) < 0.5, (dt, np.degrees(dr))
        assert pose.rms_px < 0.5


def test_wrong_side_of_board_is_not_read(rng: np.random.Generator) -> None:
    """A board seen from its +z side (the back of the print) shows mirrored tags."""
    grid = TagGrid(3, 2, 0.05, 0.01)
    T = look_at_target([-0.08, 0.05, 0.5], [0.2, 0.1, 0.0], +1.0)
    image = render(grid, T, rng)
    assert not scan(image, grid, K).found
    # Mirrored back, the same pixels read as the board: it was in view.
    assert set(scan(np.ascontiguousarray(image[:, ::-1]), grid, K).ids) == set(grid.ids)
