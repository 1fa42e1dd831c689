"""Pieces of a sampled region and their lowest saddles (methods/shape_gradient/saddles.py): which pieces are joined,
through which samples, and that the growth through the joined values is one genus-0 solid."""

from __future__ import annotations

import numpy as np
from scipy import ndimage
from skimage.measure import euler_number

from methods.shape_gradient.digital import homotopic_growth, surface_is_sphere
from methods.shape_gradient.saddles import join_pieces, piece_saddles


def _blobs(shape=(40, 20, 20)):
    """φ on a grid (voxel units): three balls of radius 3 along axis 0 at 8, 20, 32, the first two joined by a
    ridge of φ = 0.3, the last two by one of φ = 0.45 and another of φ = 0.2 (the lower one must be used)."""
    idx = np.indices(shape).astype(float)
    phi = np.full(shape, 5.0)
    for c in ((8, 10, 10), (20, 10, 10), (32, 10, 10)):
        phi = np.minimum(phi, np.sqrt(sum((idx[a] - c[a]) ** 2 for a in range(3))) - 3)
    ridges = [((11, 17), (10, 10), 0.3), ((23, 29), (10, 10), 0.45), ((23, 29), (6, 10), 0.2)]
    for (x0, x1), (y, z), w in ridges:
        for x in range(x0, x1 + 1):
            phi[x, y, z] = min(phi[x, y, z], w)
        if y != 10:                              # the second 20–32 ridge detours through y = 6
            for yy in range(6, 11):
                phi[x0, yy, z] = min(phi[x0, yy, z], w)
                phi[x1, yy, z] = min(phi[x1, yy, z], w)
    return phi


def test_the_spanning_tree_takes_each_pair_through_its_lowest_saddle():
    phi = _blobs()
    s = piece_saddles(phi, 0.0, 1.0)
    assert len(s["sizes"]) == 3 and [round(e[0], 3) for e in s["edges"]] == [0.2, 0.3]
    assert piece_saddles(phi, 0.0, 0.25)["edges"][0][0] == 0.2 and len(piece_saddles(phi, 0.0, 0.25)["edges"]) == 1
    assert piece_saddles(phi, 0.0, 0.1)["edges"] == []


def test_joined_values_grow_into_one_genus0_solid_holding_every_piece():
    phi = _blobs()
    values, facts = join_pieces(phi, 0.0, 1.0, 0.5)
    assert facts["pieces"] == 3 and facts["joins"] == 2 and facts["join_samples"] > 0
    changed = values < phi
    assert changed.any() and np.all(values <= phi)
    assert np.all(values[changed] == -0.5) and np.all(phi[changed] >= -0.5)
    # the paths are 6-connected: the lowered samples with the pieces form one 6-connected set
    assert ndimage.label(values < 0)[1] == 1
    # the 0.45 ridge is not used (the 0.2 detour is lower)
    assert not changed[23:30, 10, 10].any() and changed[23:30, 6, 10].any()
    solid = homotopic_growth(values, 0.0)
    assert np.array_equal(solid, values < 0)                 # every piece and path, nothing left out
    assert euler_number(solid, connectivity=3) == 1 and surface_is_sphere(np.where(solid, -1.0, 0.05)) is not None
    assert homotopic_growth(phi, 0.0).sum() < 0.5 * solid.sum()      # without the join: one ball


def test_pieces_beyond_the_threshold_stay_apart_and_one_piece_is_left_as_it_is():
    phi = _blobs()
    values, facts = join_pieces(phi, 0.0, 0.25, 0.5)
    assert facts["joins"] == 1 and ndimage.label(values < 0, structure=np.ones((3, 3, 3)))[1] == 2
    one = np.sqrt(((np.indices((12, 12, 12)) - 6.0) ** 2).sum(axis=0)) - 3
    same, facts = join_pieces(one, 0.0, 1.0, 0.5)
    assert same is one and facts == {"pieces": 1, "joins": 0, "join_saddles": [], "join_samples": 0}
