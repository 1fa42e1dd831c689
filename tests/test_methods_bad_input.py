"""Bad input for every baseline: no zero crossing, an open level set, wrong-type or out-of-range parameters
→ InputError naming the method (and the parameter); iteration caps and guards; the flip sweep."""

from __future__ import annotations

import time

import numpy as np
import pytest

from methods import BUILTIN_METHODS, Param, available_methods, get_method
from methods.distmesh import DistMesh, flip_edges, triangle_quality
from methods.marching_cubes import mesh_facts
from phantoms import InputError, Volume, add_noise, get_phantom

BASELINES = ["marching_cubes", "mc_taubin", "distmesh", "poisson"]


@pytest.fixture(scope="module")
def sphere24():
    return get_phantom("sphere").volume(n=24)


@pytest.mark.parametrize("method", BASELINES)
def test_no_zero_crossing(method, sphere24):
    for values in (np.full(sphere24.shape, 0.7), np.full(sphere24.shape, -0.7), np.zeros(sphere24.shape)):
        with pytest.raises(InputError, match=rf"method '{method}'.*no zero crossing"):
            get_method(method).reconstruct(sphere24.with_values(values))


@pytest.mark.parametrize("method", BASELINES)
def test_open_level_set(method):
    # the unit sphere on a grid over [-0.8, 0.8]³: the surface is cut by the grid boundary
    vol = get_phantom("sphere").volume(n=24, extent=0.8)
    with pytest.raises(InputError, match=rf"method '{method}'.*open"):
        get_method(method).reconstruct(vol)


@pytest.mark.parametrize("method", BASELINES)
def test_not_a_volume(method, sphere24):
    with pytest.raises(InputError, match=rf"method '{method}'.*expected a phantoms.Volume"):
        get_method(method).reconstruct(sphere24.values)


def _bad_values(spec: Param):
    """(wrong type, out of range) values for a parameter spec."""
    wrong = {bool: ["maybe", 2, 0.5], int: ["abc", 1.5, True], float: ["abc", "nan", True], str: [3, None]}
    bad = list(wrong.get(spec.type, []))
    out = []
    if spec.min is not None:
        out.append(spec.min - 1 if spec.type is int else spec.min - abs(spec.min) * 0.5 - 1e-3)
    if spec.max is not None:
        out.append(spec.max + 1 if spec.type is int else spec.max * 2 + 1)
    if spec.choices is not None:
        out.append("not-a-choice")
    return bad, out


@pytest.mark.parametrize("method", BASELINES)
def test_every_parameter_rejects_wrong_type_and_range(method):
    cls = available_methods()[method]
    assert cls.params, method
    for key, spec in cls.params.items():
        assert spec.doc, (method, key)
        wrong, out_of_range = _bad_values(spec)
        for value in wrong + out_of_range:
            with pytest.raises(InputError) as exc:
                get_method(method, **{key: value})
            assert f"method '{method}'" in str(exc.value) and f"parameter '{key}'" in str(exc.value), \
                (key, value, str(exc.value))
        # the default and its string form are accepted
        if spec.default is not None:
            get_method(method, **{key: spec.default})
            get_method(method, **{key: str(spec.default)})
        else:
            assert get_method(method, **{key: "auto"}).config[key] is None


def test_unknown_method_and_parameter():
    with pytest.raises(InputError, match="unknown method 'nope'; valid methods: .*marching_cubes.*poisson"):
        get_method("nope")
    with pytest.raises(InputError, match="method 'distmesh' has no parameter 'h'; valid parameters: h0"):
        get_method("distmesh", h=0.1)
    assert set(BASELINES) <= set(BUILTIN_METHODS) and set(BASELINES) <= set(available_methods())


def test_taubin_mu_below_lambda():
    with pytest.raises(InputError, match="method 'mc_taubin', parameter 'mu'"):
        get_method("mc_taubin", lamb=0.6, mu=0.5)


def test_distmesh_h0_range(sphere24):
    with pytest.raises(InputError, match="method 'distmesh', parameter 'h0'.*below half the grid spacing"):
        DistMesh(h0=0.1 * sphere24.h).reconstruct(sphere24)
    with pytest.raises(InputError, match="method 'distmesh', parameter 'h0'.*quarter"):
        DistMesh(h0=3.0).reconstruct(sphere24)


def test_distmesh_iteration_cap_reports_status(sphere24):
    t0 = time.perf_counter()
    rec = DistMesh(max_iter=7).reconstruct(sphere24)
    assert time.perf_counter() - t0 < 10
    info = rec.info
    assert info["iterations"] == 7 and info["converged"] is False and info["stop_reason"] == "max_iter"
    assert "without converging" in info["status"] and "max_iter = 7" in info["status"]
    assert len(info["max_move_history"]) == 7
    assert rec.mesh.is_watertight and rec.mesh.euler_number == 2 and rec.mesh.volume > 0


def test_distmesh_converges_on_a_coarse_sphere(sphere24):
    rec = DistMesh().reconstruct(sphere24)
    assert rec.info["converged"] and rec.info["stop_reason"] == "converged"
    assert rec.info["max_move_history"][-1] < 1e-4 and "converged after" in rec.info["status"]


def test_distmesh_divergence_guard_on_heavy_noise():
    """The original is unstable on noisy level sets; the port stops and says so instead of exploding."""
    vol, _ = add_noise(get_phantom("cylinder").volume(n=64), "gaussian", 30.0, seed=1)
    t0 = time.perf_counter()
    rec = DistMesh().reconstruct(vol)
    assert time.perf_counter() - t0 < 30
    info = rec.info
    assert info["stop_reason"] == "diverged" and not info["converged"]
    assert "diverged at iteration" in info["status"] and info["iterations"] < 2000
    assert rec.mesh.is_watertight  # still a closed mesh (folded: the metrics will show it)
    # nodes stay near the surface: the guard stops before they leave it
    assert get_phantom("cylinder").distance(np.asarray(rec.mesh.vertices)).max() < 3 * vol.h


def test_flip_sweep_on_a_10k_vertex_mesh():
    mc = get_method("marching_cubes").reconstruct(get_phantom("sphere").volume(n=128)).mesh
    p, t = np.asarray(mc.vertices), np.asarray(mc.faces)
    assert len(p) > 10_000
    t0 = time.perf_counter()
    t2, flips, rounds = flip_edges(p, t)
    assert time.perf_counter() - t0 < 10.0  # ≈ 0.2 s unloaded
    assert flips > 1000 and rounds >= 1
    import trimesh

    m2 = trimesh.Trimesh(p, t2, process=False)
    facts = mesh_facts(m2)
    assert facts["watertight"] and facts["euler"] == 2 and m2.is_winding_consistent
    assert abs(facts["signed_volume"] - mc.volume) < 1e-3 * mc.volume
    assert len(np.unique(np.sort(t2, axis=1), axis=0)) == len(t2)
    q0, _ = triangle_quality(p, *t.T)
    q1, _ = triangle_quality(p, *t2.T)
    assert q1.mean() > q0.mean()
    # a second sweep finds (almost) nothing left to flip
    assert flip_edges(p, t2)[1] == 0


def test_flip_keeps_tetrahedron_alone():
    # every edge of a tetrahedron: flipping would create an existing edge
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    t = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    t2, flips, _ = flip_edges(p, t)
    assert flips == 0 and np.array_equal(t2, t)


def test_marching_cubes_exact_zeros_on_grid_points():
    i = np.arange(20.0) - 10
    x, y, z = np.meshgrid(i, i, i, indexing="ij")
    for values in (np.maximum.reduce([abs(x), abs(y), abs(z)]) - 5, abs(x) + abs(y) + abs(z) - 6):
        assert (values == 0).any()
        mesh = get_method("marching_cubes").reconstruct(Volume(values, spacing=0.1)).mesh
        facts = mesh_facts(mesh)
        assert facts["watertight"] and facts["euler"] == 2 and facts["signed_volume"] > 0


def test_anisotropic_spacing_and_origin_are_world_coordinates():
    sph = get_phantom("sphere")
    axes = [np.linspace(-1.5, 1.5, 31), np.linspace(-1.4, 1.4, 41), np.linspace(-1.3, 1.3, 27)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    vol = Volume(sph.sdf(grid.reshape(-1, 3)).reshape(grid.shape[:3]), origin=[a[0] for a in axes],
                 spacing=[a[1] - a[0] for a in axes])
    for method in ("marching_cubes", "mc_taubin"):
        mesh = get_method(method).reconstruct(vol).mesh
        assert np.abs(np.linalg.norm(mesh.vertices, axis=1) - 1).max() < 0.5 * vol.spacing.max()


def test_poisson_two_objects_keep_largest():
    big, small = get_phantom("sphere", radius=0.9), get_phantom("sphere", radius=0.5)
    axis = np.linspace(-2.5, 2.5, 48)
    g = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    values = np.minimum(big.sdf(g - [-1.1, 0, 0]), small.sdf(g - [1.4, 0, 0])).reshape(48, 48, 48)
    vol = Volume(values, origin=[-2.5] * 3, spacing=axis[1] - axis[0])
    one = get_method("poisson").reconstruct(vol)
    assert mesh_facts(one.mesh)["components"] == 1 and one.info["raw_components"] == 2
    assert np.linalg.norm(one.mesh.vertices.mean(0) - [-1.1, 0, 0]) < 0.05  # the larger sphere
    both = get_method("poisson", keep_largest=False).reconstruct(vol)
    facts = mesh_facts(both.mesh)
    assert facts["components"] == 2 and facts["watertight"] and facts["euler"] == 4
