"""How a checker's robot, spheres and world travel into the compiled kernels.

Everything a kernel reads is in two flat arrays, ``I`` (int64) and ``F`` (float64), plus the
cloud's distance lattice (float32, its own array because it can be large; other worlds pass
a float64 placeholder, and that dtype is what compiles a kernel for them), and everything it
writes is in one scratch array ``X`` (float64). A kernel finds its data through :class:`Off`,
a named tuple of integer offsets and sizes that :func:`offsets` reads from ``I``'s header.

Why not named tuples of arrays, or sub-array views: numba reference-counts every array it
passes to a function or takes a view of, with an atomic increment and decrement, and a
configuration check touches the tables dozens of times. Measured on the UR5, that
bookkeeping cost 3x the arithmetic of a whole check; integer offsets cost nothing. Numba's
dispatch also checks each array argument of an entry point (~0.1 us each), so few arrays
also keep a single call from Python cheap.

``I`` starts with a header ``[n_int_slots, n_float_slots, (offset, length) per int slot,
(offset, length) per float slot]``; the slot numbers are below. Multi-dimensional tables
are stored row-major: ``F[o.slocal + 3 * s + a]`` is coordinate a of sphere s's centre.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
import numpy.typing as npt
from numba import njit

from gaide_core.types import FloatArray, IntArray

# -- int slots ------------------------------------------------------------------------------
# Links are ordered by the joint that carries them, spheres by their link.
I_DIMS = 0  # [J joints incl. the universe, S spheres, L links, P pairs, G groups, dof]
I_PARENT = 1  # (J,) parent joint of each joint (-1 for the universe)
I_JTYPE = 2  # (J,) JOINT_* below
I_IDXQ = 3  # (J,) column of q that drives the joint (-1: none)
I_SWORLD = 4  # (S,) 1 where sphere s is checked against the world
I_LSPH = 5  # (S,) sphere indices ordered by link
I_LSTART = 6  # (L + 1,) link l owns spheres LSPH[LSTART[l]:LSTART[l + 1]]
I_LWORLD = 7  # (L,) 1 where link l has a world-checked sphere
I_JLSTART = 8  # (J + 1,) joint j carries links JLSTART[j]:JLSTART[j + 1]
I_PAIRS = 9  # (P, 2) self-collision sphere pairs (i, j), grouped by link pair
I_GLINKS = 10  # (G, 2) the two links of each group
I_GSTART = 11  # (G + 1,) group g owns pairs GSTART[g]:GSTART[g + 1]
I_WORLD = 12  # [nx, ny, nz (cloud lattice), M primitives]; the kind is the lattice's dtype
I_PTYPE = 13  # (M,) PRIM_* below
N_I = 14
# -- float slots ----------------------------------------------------------------------------
F_PLACE_R = 0  # (J, 3, 3) joint placement in its parent joint frame
F_PLACE_T = 1  # (J, 3)
F_AXIS = 2  # (J, 3) unit axis in the joint frame
F_BASE = 3  # (4, 4) T_world_base
F_SLOCAL = 4  # (S, 3) sphere centres in their joint frames, m
F_RADII = 5  # (S,) m
F_LCENTRE = 6  # (L, 3) bounding sphere of each link's spheres, joint frame, m
F_LRADIUS = 7  # (L,) m
F_DISP = 8  # (S, dof) bound on sphere-centre motion per rad (or m) of each joint
F_LOWER = 9  # (dof,) joint limits
F_UPPER = 10  # (dof,)
F_CLOUD = 11  # [origin x, y, z / voxel, voxel, band, 1 / voxel] (as CloudWorld keeps them)
F_PR = 12  # (M, 3, 3) primitive rotations (T_world_primitive)
F_PT = 13  # (M, 3) their translations
F_PDIM = 14  # (M, 3) box: half sizes; cylinder: radius, half height, 0; sphere: radius, 0, 0
F_PBOUND = 15  # (M,) radius of a sphere about the primitive's origin that contains it
F_PDISP = 16  # (P, dof) bound on the change of pair p's centre distance per rad of each joint
# The world checks' radii: each sphere's radius plus its world raise (an extra clearance the
# oracle asks of that sphere alone; 0 otherwise), and the links' bounding radii over them.
F_WRADII = 17  # (S,) m
F_LWRADIUS = 18  # (L,) m
# (J, 3, 3, 3) a revolute joint's placement rotation P times the three terms of the rotation
# about its axis a (Rodrigues): P a a^T, P (I - a a^T) and P [a]x, so that the joint's world
# rotation is parent @ (K0 + cos q K1 + sin q K2): 9 products an entry where the placement's
# product and the rotation's took 21 (geometry.place_joint).
F_PLACE_K = 19
N_F = 20

JOINT_ROOT = 0
JOINT_REVOLUTE = 1
JOINT_PRISMATIC = 2
PRIM_BOX = 0
PRIM_CYLINDER = 1
PRIM_SPHERE = 2

# A cloud's distance lattice (float32), or the placeholder of the other worlds (float64).
# The lattice (nx * ny * nz values, row-major) is followed by the smallest value of each
# BLOCK^3 block of it (ceil(nx / BLOCK) * ceil(ny / BLOCK) * ceil(nz / BLOCK), row-major):
# see planning.compiled.tables.block_minima.
Field = npt.NDArray[np.float32] | npt.NDArray[np.float64]
BLOCK = 8

Off = namedtuple(
    "Off",
    [
        # sizes
        "J", "S", "L", "P", "G", "dof", "nx", "ny", "nz", "M",
        # offsets into I
        "parent", "jtype", "idxq", "sworld", "lsph", "lstart", "lworld", "jlstart", "pairs",
        "glinks", "gstart", "ptype",
        # offsets into F
        "place_R", "place_t", "axis", "base", "slocal", "radii", "lcentre", "lradius", "disp",
        "lower", "upper", "cloud", "pR", "pt", "pdim", "pbound", "pdisp", "wradii", "lwradius",
        "place_K",
        # offsets into X (scratch), and its size
        "xR", "xt", "xc", "xlc", "xwv", "xpv", "xreach", "xlever", "xslack", "xpreach",
        "xgreach", "xgcapped", "xsc", "xq", "xsize",
    ],
)  # fmt: skip


def pack(ints: list[IntArray], floats: list[FloatArray]) -> tuple[IntArray, FloatArray]:
    """The slots (in slot order) as one int64 array with its header and one float64 array."""
    assert len(ints) == N_I and len(floats) == N_F, "one array per slot"
    head = 2 + 2 * (len(ints) + len(floats))
    header = [len(ints), len(floats)]
    offset = head
    for a in ints:
        header += [offset, a.size]
        offset += a.size
    foffset = 0
    for f in floats:
        header += [foffset, f.size]
        foffset += f.size
    flat_i: list[IntArray] = [np.asarray(header, np.int64)]
    flat_i += [np.ravel(a).astype(np.int64) for a in ints]
    flat_f: list[FloatArray] = [np.ravel(a).astype(np.float64) for a in floats]
    return np.concatenate(flat_i), np.ascontiguousarray(np.concatenate(flat_f))


@njit(cache=True, inline="always")
def _io(I: IntArray, k: int) -> int:
    return I[2 + 2 * k]


@njit(cache=True, inline="always")
def _fo(I: IntArray, k: int) -> int:
    return I[2 + 2 * (I[0] + k)]


@njit(cache=True)
def offsets(I: IntArray) -> Off:
    """The offsets of every table in ``I`` and ``F``, and the scratch layout."""
    d = _io(I, I_DIMS)
    J, S, L, P, G, dof = I[d], I[d + 1], I[d + 2], I[d + 3], I[d + 4], I[d + 5]
    w = _io(I, I_WORLD)
    # scratch: joint rotations, translations, sphere and link centres, two samples' world
    # values and pair gaps, per-sphere reach, lever sum and slack (validity._walk), per-pair
    # reach, per-group reach, two samples' flags of the groups whose gaps are all capped, each
    # joint's sine and cosine, one configuration
    xR = 0
    xt = xR + 9 * J
    xc = xt + 3 * J
    xlc = xc + 3 * S
    xwv = xlc + 3 * L
    xpv = xwv + 2 * S
    xreach = xpv + 2 * P
    xlever = xreach + S
    xslack = xlever + S
    xpreach = xslack + S
    xgreach = xpreach + P
    xgcapped = xgreach + G
    xsc = xgcapped + 2 * G
    xq = xsc + 2 * J
    return Off(
        J, S, L, P, G, dof, I[w], I[w + 1], I[w + 2], I[w + 3],
        _io(I, I_PARENT), _io(I, I_JTYPE), _io(I, I_IDXQ), _io(I, I_SWORLD), _io(I, I_LSPH),
        _io(I, I_LSTART), _io(I, I_LWORLD), _io(I, I_JLSTART), _io(I, I_PAIRS),
        _io(I, I_GLINKS), _io(I, I_GSTART), _io(I, I_PTYPE),
        _fo(I, F_PLACE_R), _fo(I, F_PLACE_T), _fo(I, F_AXIS), _fo(I, F_BASE), _fo(I, F_SLOCAL),
        _fo(I, F_RADII), _fo(I, F_LCENTRE), _fo(I, F_LRADIUS), _fo(I, F_DISP), _fo(I, F_LOWER),
        _fo(I, F_UPPER), _fo(I, F_CLOUD), _fo(I, F_PR), _fo(I, F_PT), _fo(I, F_PDIM),
        _fo(I, F_PBOUND), _fo(I, F_PDISP), _fo(I, F_WRADII), _fo(I, F_LWRADIUS),
        _fo(I, F_PLACE_K),
        xR, xt, xc, xlc, xwv, xpv, xreach, xlever, xslack, xpreach, xgreach, xgcapped, xsc,
        xq, xq + dof,
    )  # fmt: skip
