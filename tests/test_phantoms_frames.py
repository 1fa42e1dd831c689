"""phantoms/frames.py: the frame a misplaced surface is in — world, LPS, or the file's voxel indices."""

from __future__ import annotations

import numpy as np
import trimesh

from phantoms import get_phantom
from phantoms.frames import distance_in_voxels, fitting_frame


def test_a_surface_in_lps_or_in_voxel_indices_is_named_and_one_in_place_is_not():
    vol = get_phantom("sphere").volume(n=32)                 # a ±2.5 grid; φ: a unit sphere off the centre
    centre = np.array([0.4, 0.3, 0.0])
    vol = vol.with_values(np.linalg.norm(vol.grid_points() - centre, axis=-1) - 1.0)
    v = trimesh.creation.icosphere(subdivisions=3).vertices + centre
    assert distance_in_voxels(v, vol) < 0.1 and fitting_frame(v, vol) is None
    assert fitting_frame(v * [-1, -1, 1], vol).startswith("LPS coordinates (negate x and y")
    index = (v - vol.origin) / vol.spacing
    assert fitting_frame(index, vol).startswith("voxel-index coordinates of the file")
    flipped = index.copy()
    flipped[:, 0] = vol.shape[0] - 1 - flipped[:, 0]          # the file stored x reversed
    assert fitting_frame(flipped, vol).startswith("voxel-index coordinates of the file")
    assert fitting_frame(v + [0.6, 0.0, 0.0], vol) is None     # merely shifted: no frame fits
