"""Bad input for every baseline: no zero crossing, an open level set, wrong-type or out-of-range parameters
→ InputError naming the method (and the parameter).  (DistMesh's own guards: test_methods_distmesh.py.)"""

from __future__ import annotations

import numpy as np
import pytest

from geometry.mesh import mesh_facts
from methods import Param, available_methods, get_method
from methods.registry import BUILTIN_METHODS
from phantoms import InputError, Volume, get_phantom

BASELINES = ["marching_cubes", "mc_taubin", "distmesh", "poisson", "flying_edges", "reach_for_the_spheres",
             "dual_contouring", "reach_for_the_arcs"]


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
