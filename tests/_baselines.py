"""The baselines' accuracy check on the clean sdf phantoms at N = 96, shared by their mirrored test files
(``test_methods_marching_cubes.py``, ``test_methods_mc_taubin.py``, ``test_methods_poisson.py``,
``test_methods_distmesh.py``; not collected: the name starts with an underscore).

Each reconstruction must be a watertight, outward-oriented (positive signed volume) mesh with Euler
characteristic 2 whose vertices lie within 0.5 grid spacings (marching cubes, MC + Taubin) or 1.5 grid
spacings (DistMesh, screened Poisson) of the true surface, measured with the phantom's exact distance.
Each (method, phantom) pair is reconstructed once per test process.
"""

from __future__ import annotations

import numpy as np

from geometry.mesh import mesh_facts
from methods import Reconstruction, get_method
from phantoms import get_phantom

N = 96
PHANTOMS = ["sphere", "ellipsoid", "fused_spheres", "cylinder"]
TOLERANCE_H = {"marching_cubes": 0.5, "mc_taubin": 0.5, "distmesh": 1.5, "poisson": 1.5}

_volumes: dict = {}
_results: dict = {}


def volume(name):
    if name not in _volumes:
        _volumes[name] = get_phantom(name).volume(n=N)
    return _volumes[name]


def reconstruct(method: str, phantom: str) -> Reconstruction:
    key = (method, phantom)
    if key not in _results:
        _results[key] = get_method(method).reconstruct(volume(phantom))
    return _results[key]


def check(method: str, phantom: str) -> None:
    rec = reconstruct(method, phantom)
    vol = volume(phantom)
    mesh = rec.mesh
    facts = mesh_facts(mesh)
    assert facts["watertight"], f"{method} on {phantom}: not watertight"
    assert facts["euler"] == 2, f"{method} on {phantom}: Euler characteristic {facts['euler']}"
    assert facts["components"] == 1
    assert facts["signed_volume"] > 0, f"{method} on {phantom}: faces point inward"
    assert mesh.is_winding_consistent
    d = get_phantom(phantom).distance(np.asarray(mesh.vertices)) / vol.h
    assert d.max() <= TOLERANCE_H[method], f"{method} on {phantom}: max vertex distance {d.max():.3f} h"
    # the enclosed volume is the phantom's to within a few per cent
    true_volume = {"sphere": 4 / 3 * np.pi, "ellipsoid": 4 / 3 * np.pi * 2.0, "cylinder": np.pi * 0.16 * 2.0}
    if phantom in true_volume:
        assert abs(facts["signed_volume"] / true_volume[phantom] - 1) < 0.03
    # vertices are in world coordinates inside the volume box
    assert vol.contains(np.asarray(mesh.vertices)).all()
    assert isinstance(rec.info, dict) and "iterations" in rec.info
