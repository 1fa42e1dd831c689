"""Tests of ``methods.shape_gradient.method``: the :class:`ShapeGradient` Method — its parameters and presets,
what ``prepare`` resolves from the volume (beta='auto', the noise variance), the user's initial mesh and centre,
and the volumes it refuses."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from _shape_gradient_common import SG, hausdorff
from methods import get_method
from methods.shape_gradient import ShapeGradient
from phantoms import InputError, Volume, add_noise, get_phantom


@pytest.fixture(scope="module")
def sphere32():
    return get_phantom("sphere").volume(n=32)


def test_registry_and_parameters():
    m = get_method("shape_gradient", alpha="3", max_iter="7")
    assert isinstance(m, ShapeGradient) and m.config["alpha"] == 3.0 and m.config["max_iter"] == 7
    for p in ("alpha", "beta", "gradient", "max_move", "precondition", "s", "relax", "presmooth",
              "max_iter", "tol", "init_radius", "init_vertices", "init_mesh", "snapshots", "preset"):
        assert p in ShapeGradient.params and ShapeGradient.params[p].doc
    with pytest.raises(InputError):
        SG(gradient="exact")
    with pytest.raises(InputError):
        SG(alpha=-1)
    with pytest.raises(InputError):
        SG(presmooth="lots")
    with pytest.raises(InputError):
        SG(snapshots="1,x")
    with pytest.raises(InputError):
        SG(bogus=1)
    with pytest.raises(InputError):
        SG(polish="maybe")
    with pytest.raises(InputError):
        SG(max_move=0)


def test_paper_preset():
    m = SG(preset="paper")
    c = m.config
    assert (c["gradient"], c["precondition"], c["curvature"], c["relax"], c["presmooth"]) == \
        ("paper", "none", "paper", 0.0, 0.0)
    assert c["polish"] == "off"
    assert SG(preset="paper", relax=0.3).config["relax"] == 0.3   # explicit wins


def test_beta_auto_follows_the_noise(sphere32):
    noisy, _ = add_noise(sphere32, "gaussian", 40.0, seed=0)
    assert SG(max_iter=2, guard=False).reconstruct(sphere32).info["beta_used"] == 1.0
    assert SG(max_iter=2, guard=False).reconstruct(noisy).info["beta_used"] == 0.01
    assert SG(max_iter=2, guard=False, beta=0.5).reconstruct(noisy).info["beta_used"] == 0.5
    assert SG().config["beta"] == "auto" and SG(beta="2").config["beta"] == 2.0
    with pytest.raises(InputError, match="'beta'"):
        SG(beta="strong")
    with pytest.raises(InputError, match="'start_smooth'"):
        SG(start_smooth=-1)


def test_noisy_volumes_subtract_the_noise_variance(sphere32):
    noisy, _ = add_noise(sphere32, "gaussian", 40.0, seed=0)
    r = SG(max_iter=2, guard=False).reconstruct(noisy)
    sigma = r.info["noise_estimate"]
    assert r.info["parameters"]["noise_variance"] == pytest.approx((2 / 3) ** 3 * sigma ** 2) and sigma > 0
    assert SG(max_iter=2, guard=False, unbias=False).reconstruct(noisy).info["parameters"]["noise_variance"] == 0
    assert SG(max_iter=2, guard=False).reconstruct(sphere32).info["parameters"]["noise_variance"] == 0   # clean


def test_user_init_mesh_and_the_sphere_about_the_grid_centre(sphere32):
    ico = trimesh.creation.icosphere(subdivisions=3, radius=1.6)
    r = SG(init_mesh=ico).reconstruct(sphere32)
    assert len(r.mesh.vertices) == len(ico.vertices)
    assert hausdorff(r.mesh, get_phantom("sphere"), 5000) <= 0.3 * sphere32.h
    # an inward-oriented mesh is flipped, a (vertices, faces) pair works too
    r2 = SG(init_mesh=(ico.vertices, ico.faces[:, ::-1]), max_iter=2).reconstruct(sphere32)
    assert r2.info["init_flipped"] and r2.mesh.volume > 0
    r3 = SG(init="sphere", init_radius=1.5, max_iter=0, guard=False, projection="off",
            reach_samples=False).reconstruct(sphere32)
    np.testing.assert_allclose(r3.mesh.vertices.mean(0), 0.5 * (sphere32.lower + sphere32.upper), atol=1e-3)


def test_rejects_volumes_that_do_not_contain_the_initial_surface(sphere32):
    with pytest.raises(InputError, match="outside the volume box"):
        SG(init_radius=3.0).reconstruct(sphere32)
    far = trimesh.creation.icosphere(subdivisions=2).apply_translation([2.0, 0, 0])
    with pytest.raises(InputError, match="outside the volume box"):
        SG(init_mesh=far).reconstruct(sphere32)
    with pytest.raises(InputError):
        SG().reconstruct(Volume(np.ones((16, 16, 16))))         # no zero crossing
    with pytest.raises(InputError):
        SG().reconstruct(np.zeros((8, 8, 8)))                     # not a Volume


def test_max_faces_ties_the_mesh_size_to_the_surface_area():
    """With a face budget below what edge_length needs, the remeshing's edge length grows so the mesh has about
    that many faces — and the result still lies on the surface; without it the count follows edge_length."""
    ph = get_phantom("sphere")
    vol = ph.volume(n=48)
    free = ShapeGradient(max_iter=10).reconstruct(vol)
    capped = ShapeGradient(max_iter=10, max_faces=3000).reconstruct(vol)
    assert len(free.mesh.faces) > 2 * 3000
    assert 0.5 * 3000 <= len(capped.mesh.faces) <= 1.5 * 3000
    assert capped.info["init"]["edge_length_voxels_for_max_faces"] > 0.5
    assert "edge_length_voxels_for_max_faces" not in free.info["init"]
    d = np.abs(ph.sdf(capped.mesh.vertices))
    assert d.max() < 0.2 * vol.h
