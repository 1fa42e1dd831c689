"""Tests of ``phantoms.mesh.grid_sdf`` (and its compiled kernels, ``grid_kernels.py``): the grid signed
distance of a mesh phantom in bounded memory:
the same values as before the rewrite in the band, an upper bound beyond, a certified closest-face query,
and the memory of a bunny volume measured in a child process."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import trimesh

from phantoms import MeshPhantom, get_phantom
from phantoms.mesh.grid_sdf import closest_faces


@pytest.fixture(scope="module")
def bunny():
    return get_phantom("bunny")


def test_bunny_volume_equals_the_previous_implementation_in_the_band(bunny):
    from _grid_sdf_reference import signed_distance_grid as reference

    n = 48
    h = 5.0 / (n - 1)
    stats = {}
    old = reference(bunny.index, n, 2.5, stats=stats)
    new = bunny.signed_distance_grid(n, 2.5)
    band = stats["band_mask"].reshape(n, n, n)                 # where the old volume was certified exact
    assert band.sum() > 5000
    assert np.abs(new - old)[band].max() <= 1e-9 * h
    assert np.array_equal(np.sign(new), np.sign(old))
    # beyond the band both are upper bounds, close to each other
    assert np.abs(np.abs(new) - np.abs(old))[~band].max() < 0.05 * h


def test_closest_faces_is_the_certified_query(bunny):
    rng = np.random.default_rng(4)
    x, _ = bunny.sample_surface(300, seed=3)
    p = np.concatenate([rng.uniform(-2.5, 2.5, (700, 3)),           # near and far
                        x + rng.normal(scale=0.02, size=x.shape),   # next to the surface
                        rng.normal(size=(50, 3)) * 6.0])            # outside the cell grid
    f = closest_faces(bunny.index, p)
    d = bunny.index.eval_pairs(p, f.astype(np.int64))[0]
    _, d_ref, _, _, _ = bunny.closest(p)
    assert np.abs(d - d_ref).max() <= 1e-12


def test_icosphere_far_field_is_an_upper_bound_and_exact_in_the_band():
    m = trimesh.creation.icosphere(subdivisions=3, radius=1.5)
    ph = MeshPhantom(np.asarray(m.vertices), np.asarray(m.faces), name="ico")
    n = 32
    g = ph.signed_distance_grid(n, 2.5).ravel()
    h = 5.0 / (n - 1)
    axis = -2.5 + h * np.arange(n)
    pts = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    exact = ph.sdf(pts)
    assert np.array_equal(np.sign(g), np.sign(exact))
    band = np.abs(exact) <= 3 * h
    assert np.abs(g - exact)[band].max() <= 1e-12
    err = np.abs(g) - np.abs(exact)
    assert err.min() >= -1e-12 and err.max() < 0.05 * h


def test_a_grid_that_misses_the_surface_is_signed_from_a_seed():
    m = trimesh.creation.icosphere(subdivisions=2, radius=1.5)
    ph = MeshPhantom(np.asarray(m.vertices), np.asarray(m.faces), name="ico")
    g = ph.signed_distance_grid(12, 0.5)                       # the grid lies inside the sphere: no band
    assert (g < 0).all()
    h = 1.0 / 11
    axis = -0.5 + h * np.arange(12)
    pts = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    err = np.abs(g.ravel()) - np.abs(ph.sdf(pts))
    assert err.min() >= -1e-12 and err.max() < 0.05 * h


_SCRIPT = textwrap.dedent("""
    import json, sys
    sys.path.insert(0, {root!r})

    def status(key):
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith(key + ":"):
                    return int(line.split()[1]) * 1024
        return 0

    from phantoms import get_phantom
    ph = get_phantom("bunny")
    ph.volume(n=16)                                   # loads the compiled kernels
    ph._volume_cache.clear()
    base = status("VmRSS")
    vol = ph.volume(n={n})
    print(json.dumps({{"base": base, "hwm": status("VmHWM"), "out": vol.values.nbytes}}))
""")


@pytest.mark.heavy
def test_bunny_volume_memory_is_bounded_by_four_outputs():
    root = str(Path(__file__).resolve().parents[1])
    out = subprocess.run([sys.executable, "-c", _SCRIPT.format(root=root, n=160)], capture_output=True,
                         text=True, timeout=900, check=True)
    res = json.loads(out.stdout.strip().splitlines()[-1])
    print(res)
    # the volume's own peak (VmHWM since the kernels were loaded): the cached array and the returned copy,
    # and the propagation's arrays (2.4 outputs) while it runs
    assert res["hwm"] - res["base"] <= 4 * res["out"]


def test_a_mesh_volume_larger_than_the_memory_is_refused_before_it_is_computed(monkeypatch):
    import phantoms.memory as pv
    from phantoms import InputError

    m = trimesh.creation.icosphere(subdivisions=2, radius=1.5)
    ph = MeshPhantom(np.asarray(m.vertices), np.asarray(m.faces), name="ico")
    monkeypatch.setattr(pv, "available_memory", lambda: 64 ** 3 * 24 - 1)
    with pytest.raises(InputError, match="largest N³ grid that fits is N = 63"):
        ph.volume(n=64)
    assert ph.volume(n=63).shape == (63, 63, 63)
