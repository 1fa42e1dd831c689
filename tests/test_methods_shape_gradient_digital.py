"""methods.shape_gradient.digital: the simple-point test against its scipy reference, the homotopic growth's topology
(one component, no handle, no cavity) on volumes with known handles, and marching cubes of ball_field giving exactly
one closed genus-0 surface — also on random fields full of handles."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage
from skimage.measure import euler_number, label

from geometry.compiled import AVAILABLE
from methods.shape_gradient.digital import (
    _ADJ6,
    _ADJ26,
    _ALL,
    _FACE6,
    _N18,
    NEIGHBOUR_OFFSETS,
    _is_simple,
    ambiguous_cells,
    ball_field,
    homotopic_growth,
    is_simple_reference,
    surface_is_sphere,
)


def _grid(n=32, lo=-1.6, hi=1.6):
    t = np.linspace(lo, hi, n)
    return np.meshgrid(t, t, t, indexing="ij"), t[1] - t[0]


def torus(n=32, R=0.9, r=0.35):
    (x, y, z), h = _grid(n)
    return np.hypot(np.hypot(x, y) - R, z) - r, h


def random_field(seed, n=28):
    rng = np.random.default_rng(seed)
    phi = ndimage.gaussian_filter(rng.standard_normal((n, n, n)), 1.0 + 0.5 * (seed % 3))
    return phi / phi.std() + (0.3 if seed % 2 else -0.2)


def is_ball(solid):
    """One 26-component, χ = 1 (26/6), and a connected 6-background: a topological ball."""
    return (label(solid, connectivity=3).max() == 1 and euler_number(solid, connectivity=3) == 1
            and label(~solid, connectivity=1).max() == 1)


@pytest.mark.skipif(not AVAILABLE, reason="numba missing: the reference is the implementation")
def test_simple_point_kernel_equals_the_scipy_reference():
    rng = np.random.default_rng(0)
    n_simple = 0
    for density in (0.2, 0.5, 0.8):
        for _ in range(400):
            block = rng.random((3, 3, 3)) < density
            block[1, 1, 1] = False
            pad = np.zeros((5, 5, 5), bool)
            pad[1:4, 1:4, 1:4] = block
            got = bool(_is_simple(pad, 2, 2, 2, NEIGHBOUR_OFFSETS, _ADJ6, _ADJ26, _N18, _FACE6, _ALL))
            want = is_simple_reference(block)
            assert got == want, block.astype(int)
            n_simple += want
    assert 100 < n_simple < 1100          # both outcomes are exercised


def test_simple_points_by_hand():
    block = np.zeros((3, 3, 3), bool)
    assert not is_simple_reference(block)             # an isolated point: adding it makes a new component
    block[0, 1, 1] = True
    assert is_simple_reference(block)                 # a point at the end of a line
    block[2, 1, 1] = True
    assert not is_simple_reference(block)             # it would join two components
    ring = np.zeros((3, 3, 3), bool)
    ring[:, :, 1] = True
    ring[1, 1, 1] = False
    assert not is_simple_reference(ring)              # it would fill the hole of a ring (close a tunnel)
    full = np.ones((3, 3, 3), bool)
    assert not is_simple_reference(full)              # it would fill a cavity


def test_growth_equals_the_reference_growth():
    phi = random_field(3, n=14)
    assert np.array_equal(homotopic_growth(phi), homotopic_growth(phi, reference=True))


def test_a_ball_is_grown_whole():
    (x, y, z), h = _grid(24)
    phi = np.sqrt(x ** 2 + y ** 2 + z ** 2) - 1.0
    solid = homotopic_growth(phi)
    assert np.array_equal(solid, phi < 0)


def test_a_torus_is_cut_once_where_it_is_thinnest():
    (x, y, z), h = _grid(32)
    # the tube is thinner near x < 0: r = 0.35 + 0.1·x/R
    phi = np.hypot(np.hypot(x, y) - 0.9, z) - (0.35 + 0.1 * x / 0.9)
    solid = homotopic_growth(phi)
    inside = phi < 0
    assert euler_number(inside, connectivity=3) == 0              # the target has a handle
    assert is_ball(solid) and not (solid & ~inside).any()
    cut = inside & ~solid
    assert 0 < cut.sum() < 0.05 * inside.sum()                   # a thin slice, not a chunk
    assert np.all(x[cut] < 0)                                    # on the thin side of the tube


def test_two_objects_and_a_cavity():
    (x, y, z), h = _grid(32)
    two = np.minimum(np.sqrt((x - 0.8) ** 2 + y ** 2 + z ** 2) - 0.5, np.sqrt((x + 0.8) ** 2 + y ** 2 + z ** 2) - 0.6)
    solid = homotopic_growth(two)
    assert is_ball(solid) and np.array_equal(solid, (two < 0) & (x < 0))   # the deeper (larger) one only
    r = np.sqrt(x ** 2 + y ** 2 + z ** 2)
    shell = np.maximum(r - 1.2, 0.6 - r)
    solid = homotopic_growth(shell)
    assert is_ball(solid) and 0 < ((shell < 0) & ~solid).sum() < 0.05 * (shell < 0).sum()   # the shell is opened


def test_the_largest_object_is_grown_not_the_deepest_fragment():
    """A small fragment with the deepest values (a mis-signed sliver of a flawed mesh's distance field) must not
    become the start: the cow of pymeshlab's samples gave a 16-sample solid of 7,476 inside samples."""
    (x, y, z), h = _grid(32)
    big = np.sqrt((x + 0.5) ** 2 + y ** 2 + z ** 2) - 0.9
    frag = 10.0 * (np.sqrt((x - 1.2) ** 2 + y ** 2 + z ** 2) - 0.25)       # far deeper, a few samples
    phi = np.minimum(big, frag)
    assert phi.argmin() == frag.argmin()
    solid = homotopic_growth(phi)
    assert is_ball(solid) and np.array_equal(solid, big < 0)


def test_no_inside_sample_gives_an_empty_solid():
    assert not homotopic_growth(np.ones((8, 8, 8))).any()
    phi = np.ones((8, 8, 8))
    phi[0] = -1.0                                   # inside only on the outer layer: never grown
    assert not homotopic_growth(phi).any()


def test_ambiguous_cells():
    inside = np.zeros((2, 2, 2), bool)
    inside[0, 0, 0] = inside[1, 1, 0] = True        # a face with diagonal signs
    assert ambiguous_cells(inside).all()
    inside[:] = False
    inside[0, 0, 0] = inside[1, 1, 1] = True        # body diagonal
    assert ambiguous_cells(inside).all()
    inside[:] = False
    inside[0, :, :] = True                          # a plane: no ambiguity
    assert not ambiguous_cells(inside).any()


def test_ball_field_on_a_torus_is_one_genus_0_surface_near_the_torus():
    phi, h = torus()
    solid = homotopic_growth(phi)
    field, (v, f), how = ball_field(phi, solid, h)
    assert surface_is_sphere(field) is not None
    # away from the cut every vertex is on the torus' zero set (marching cubes' accuracy: a few hundredths of h)
    t = np.linspace(-1.6, 1.6, 32)
    p = t[0] + v * h
    d = np.abs(np.hypot(np.hypot(p[:, 0], p[:, 1]) - 0.9, p[:, 2]) - 0.35)
    assert np.median(d) < 0.05 * h and np.mean(d > 0.5 * h) < 0.1


@pytest.mark.parametrize("seed", range(12))
def test_ball_field_on_random_fields_full_of_handles(seed):
    phi = random_field(seed)
    inside = phi < 0
    assert euler_number(inside, connectivity=3) != 1 or label(inside, connectivity=3).max() != 1
    solid = homotopic_growth(phi)
    assert is_ball(solid)
    field, mesh, how = ball_field(phi, solid, 1.0)
    assert mesh is not None, how
    assert np.array_equal(field < 0, solid)          # the surface separates exactly the solid's samples


def _join_faces_dense(phi, rounds=4, margin=1.5):
    """The whole-grid form of the face fix (every face tested every round): the reference the sparse one in
    digital.py must equal bit for bit."""
    phi = phi.copy()
    for _ in range(rounds):
        changed = False
        for ax in range(3):
            o0, o1 = [a for a in range(3) if a != ax]

            def corner(d0, d1):
                sl = [slice(None)] * 3
                sl[o0] = slice(d0, phi.shape[o0] - 1 + d0)
                sl[o1] = slice(d1, phi.shape[o1] - 1 + d1)
                return phi[tuple(sl)]
            a, b, c, d = corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)
            for p, q, r, s in ((a, b, c, d), (b, c, d, a)):
                bad = (p < 0) & (r < 0) & (q >= 0) & (s >= 0) & (p * r <= margin * q * s)
                if bad.any():
                    with np.errstate(divide="ignore", invalid="ignore"):
                        f = np.sqrt(np.where(bad, p * r / (margin * q * s), 1.0))
                    f = np.where(bad, np.minimum(f, 1.0) * 0.999, 1.0)
                    q *= f
                    s *= f
                    changed = True
        if not changed:
            break
    return phi


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_face_fix_equals_the_whole_grid_reference(seed):
    """Random fields (many faces with diagonal signs, samples that are corners of several such faces, zeros)
    and a smooth one: the sparse face fix changes exactly what the whole-grid one does."""
    from methods.shape_gradient.digital import _join_faces

    rng = np.random.default_rng(seed)
    phi = rng.normal(size=(13, 11, 9))
    phi[rng.random(phi.shape) < 0.05] = 0.0
    fixed = _join_faces(phi)
    assert np.array_equal(fixed, _join_faces_dense(phi))
    assert not np.array_equal(fixed, phi) and np.array_equal(fixed < 0, phi < 0)
    g = np.linspace(-1, 1, 24)
    x, y, z = np.meshgrid(g, g, g, indexing="ij")
    smooth = np.sin(7 * x + seed) * np.cos(5 * y) + 0.3 * z
    assert np.array_equal(_join_faces(smooth), _join_faces_dense(smooth))
