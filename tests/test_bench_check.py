"""bench.check: the test volumes of ``check-method`` have the zero sets they claim, and each kind of broken
output is judged as the contract says (violation named, with what to fix)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from bench.check import CASES, case_volumes, check_method, hint, run_case
from methods import Method, Reconstruction, ReconstructionFailed, get_method
from phantoms import InputError


@pytest.fixture(scope="module")
def volumes():
    return case_volumes(24)


def _phi(vol, points):
    return vol.sample(np.asarray(points, float)).phi


def test_the_cases_have_their_analytic_zero_sets(volumes):
    assert tuple(volumes) == CASES
    sphere, _ = volumes["sphere"]
    d = np.array([[1.0, 0, 0], [0, -1.0, 0], [0, 0, 0.6], [0.7071, 0.7071, 0]])
    assert np.allclose(_phi(sphere, d), [0, 0, -0.4, 0], atol=0.02)      # trilinear φ of |p| − 1
    ell, _ = volumes["anisotropic"]
    assert len(set(np.round(ell.spacing, 6))) == 3 and len(set(ell.shape)) == 3     # per-axis spacing and size
    assert np.all(ell.origin != 0)
    centre, axes = np.array([0.4, -0.3, 0.2]), np.array([1.0, 0.7, 0.5])
    tips = centre + np.diag(axes)                                      # the ends of the three semi-axes
    assert np.allclose(_phi(ell, tips), 0, atol=0.01)
    assert _phi(ell, centre[None])[0] < 0 and _phi(ell, (centre + 1.05 * np.diag(axes))).min() > 0
    torus, _ = volumes["torus"]
    ring = np.array([[1.45, 0, 0], [0, 0.55, 0], [1.0, 0, 0.45], [0, 0, 0]])
    assert np.allclose(_phi(torus, ring)[:3], 0, atol=0.02) and _phi(torus, ring)[3] > 0.4  # the hole is outside
    noisy, clean = volumes["noisy"]
    assert clean is sphere and not np.array_equal(noisy.values, clean.values)
    snr = 10 * np.log10(np.mean(clean.values**2) / np.var(noisy.values - clean.values))
    assert abs(snr - 30.0) < 0.5
    empty, _ = volumes["no_surface"]
    assert not empty.has_zero_crossing()


def _mc(volume):
    return get_method("marching_cubes").reconstruct(volume).mesh


class _Returns(Method):
    """A test method whose output is made by ``make(volume)``."""

    name = "test_returns"
    make = None

    def reconstruct(self, volume):
        return type(self).make(volume)


def _case(make, case="anisotropic"):
    cls = type("M", (_Returns,), {"make": staticmethod(make)})
    vol, clean = case_volumes(24)[case]
    return run_case(cls(), case, vol, clean)


def test_a_valid_result_passes_and_keeps_the_info():
    r = _case(lambda v: Reconstruction(_mc(v), {"iterations": 3, "my_counter": np.int64(7)}))
    assert r.passed and r.outcome == "mesh" and r.info == {"iterations": 3, "my_counter": 7}
    assert r.facts["euler"] == 2 and r.seconds >= 0


@pytest.mark.parametrize("make, reason", [
    (lambda v: Reconstruction(trimesh.Trimesh(v.world_to_index(_mc(v).vertices), _mc(v).faces, process=False)),
     "outside the volume"),
    (lambda v: Reconstruction(trimesh.Trimesh(_mc(v).vertices[:, ::-1], _mc(v).faces[:, ::-1], process=False)),
     ("off the zero set", "outside the volume")),                       # x and z swapped (a transposed volume)
    (lambda v: Reconstruction(trimesh.Trimesh(_mc(v).vertices, _mc(v).faces[:, ::-1], process=False)), "inward"),
    (lambda v: Reconstruction(trimesh.Trimesh(_mc(v).vertices, _mc(v).faces[1:], process=False)), "open"),
    (lambda v: _mc(v), "wrong type"),
    (lambda v: (_mc(v), {}), "wrong type"),
    (lambda v: Reconstruction(_mc(v), [("iterations", 1)]), "wrong type"),
    (lambda v: 1 / 0, "raised ZeroDivisionError"),
    (lambda v: (_ for _ in ()).throw(ReconstructionFailed("gave up")), "raised ReconstructionFailed"),
])
def test_each_broken_output_is_named_with_a_fix(make, reason):
    r = _case(make)
    reasons = reason if isinstance(reason, tuple) else (reason,)
    assert not r.passed and len(r.violations) == 1 and r.violations[0].startswith(reasons), r.violations
    assert hint(r.violations[0])


def test_no_surface_passes_a_refusal_or_an_empty_mesh_and_fails_a_surface():
    def refuse(v):
        raise InputError("nothing there")

    assert _case(refuse, "no_surface").passed
    assert _case(lambda v: Reconstruction(trimesh.Trimesh(), {}), "no_surface").outcome == "empty mesh"
    assert _case(lambda v: Reconstruction(trimesh.Trimesh(), {}), "no_surface").passed
    bad = _case(lambda v: Reconstruction(trimesh.creation.icosphere(1), {}), "no_surface")
    assert not bad.passed and bad.violations[0].startswith("surface")
    crash = _case(lambda v: np.zeros(2)[5], "no_surface")
    assert not crash.passed and "IndexError" in crash.violations[0]


def test_a_refusal_passes_on_the_torus_but_not_on_the_sphere():
    def refuse(v):
        raise ReconstructionFailed("genus 0 only")

    assert _case(refuse, "torus").passed
    assert not _case(refuse, "sphere").passed


def test_check_method_runs_the_chosen_cases():
    res = check_method(get_method("marching_cubes"), cases=("sphere", "torus"))
    assert [r.case for r in res] == ["sphere", "torus"] and all(r.passed for r in res)
    assert res[1].facts["euler"] == 0


def test_a_method_raising_keyboard_interrupt_is_a_finding_not_a_child_traceback(monkeypatch):
    from bench.check import check_method
    from methods import get_method
    from methods.marching_cubes import MarchingCubes

    def interrupt(self, volume):
        raise KeyboardInterrupt

    monkeypatch.setattr(MarchingCubes, "reconstruct", interrupt)
    results = check_method(get_method("marching_cubes"), cases=("sphere", "no_surface"), timeout=30)
    for res in results:
        assert res.outcome == "raised" and res.violations[0].startswith("raised KeyboardInterrupt"), res
        assert "Traceback" not in (res.output or "")


# ------------------------------------------------------------------ the method's hooks: skip_reason and warm_up
@pytest.fixture()
def hooks(monkeypatch):
    import hook_plugins

    monkeypatch.setattr(hook_plugins, "_WARMED", [])
    return hook_plugins


def test_a_declined_case_is_skipped_with_its_reason_not_a_violation(hooks):
    results = {r.case: r for r in check_method(get_method("picky_mc", min_n=26), cases=CASES)}
    assert results["sphere"].outcome == "skipped" and results["sphere"].passed        # the sphere's N is 24
    assert "skipped: the grid has 24 points per axis, fewer than the 26 it needs" in results["sphere"].notes
    assert results["torus"].outcome == "mesh" and all(r.passed for r in results.values())


def test_skipping_every_case_is_a_violation_nothing_was_checked(hooks):
    results = check_method(get_method("picky_mc"), cases=("sphere", "torus"))
    assert [r.outcome for r in results] == ["skipped", "skipped"]
    assert results[0].violations == ["skipped every case: nothing was checked"] and hint(results[0].violations[0])


def test_warm_up_runs_before_the_case_and_outside_its_time(hooks):
    first, second = check_method(get_method("warm_mc"), cases=("sphere", "torus"))
    assert first.passed and second.passed
    assert first.warm_up_s >= hooks.WARM_SECONDS > first.seconds and second.warm_up_s < hooks.WARM_SECONDS


@pytest.mark.parametrize("hook, outcome, says", [("skip_type", "wrong type", "skip_reason returned 3"),
                                                 ("skip_raises", "raised", "ValueError: no idea"),
                                                 ("warm_raises", "raised", "the kernels do not compile")])
def test_a_hook_breaking_its_contract_is_a_violation(hooks, hook, outcome, says):
    (res,) = check_method(get_method("bad_hooks", hook=hook), cases=("no_surface",))
    assert res.outcome == outcome and len(res.violations) == 1 and says in res.violations[0]
