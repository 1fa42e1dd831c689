"""The start choice (methods/shape_gradient/choose.py): the data residual against analytic distances, the pick's
rule, when the choice runs, and that it keeps a part only the carved start has and the usual start where the
carved ones add nothing."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from methods.shape_gradient import ShapeGradient
from methods.shape_gradient.choose import (AGREE_NOISE_STDS, AGREE_VOXELS, CANDIDATES, PREFER_USUAL, USUAL_START,
                                          data_errors, data_residual, lacks_a_part, pick, start_candidates,
                                          start_settings)
from phantoms import Volume

from _shape_gradient_common import far_limb_volume

_N, _LO, _R = 32, -2.0, 1.2
_H = 4.0 / (_N - 1)


def _sphere_volume(n=_N):
    g = _LO + (4.0 / (n - 1)) * np.arange(n)
    p = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1)
    return Volume(np.linalg.norm(p, axis=-1) - _R, [_LO] * 3, 4.0 / (n - 1))


def _sphere_mesh(radius):
    m = trimesh.creation.icosphere(subdivisions=5, radius=1.0)     # its faces sag ~10⁻⁴ r: below the tolerance
    return np.asarray(m.vertices) * radius, np.asarray(m.faces)


def test_the_residual_is_the_distance_error_in_voxels():
    """On an exact sphere distance: the sphere itself scores near 0; a sphere larger by half a voxel is off by
    −½ voxel at every band sample (d_Γ = |q| − r − h/2 against φ = |q| − r), so it scores ½; a sphere off-centre
    by a voxel scores between (rms of cos over the band: about 1/√3)."""
    vol = _sphere_volume()
    exact = data_residual(vol, *_sphere_mesh(_R))
    larger = data_residual(vol, *_sphere_mesh(_R + 0.5 * _H))
    v, f = _sphere_mesh(_R)
    shifted = data_residual(vol, v + [_H, 0.0, 0.0], f)
    assert exact < 0.02
    assert larger == pytest.approx(0.5, abs=0.02)
    assert 0.45 < shifted < 0.7


def test_the_residual_counts_a_missing_part():
    """Two balls in the data, one in the mesh: the samples around the missing ball are far from the mesh."""
    g = _LO + _H * np.arange(_N)
    p = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1)
    values = np.minimum(np.linalg.norm(p - [1.0, 0, 0], axis=-1), np.linalg.norm(p + [1.0, 0, 0], axis=-1)) - 0.6
    vol = Volume(values, [_LO] * 3, _H)
    v, f = _sphere_mesh(0.6)
    both = trimesh.util.concatenate([trimesh.Trimesh(v + [1.0, 0, 0], f), trimesh.Trimesh(v - [1.0, 0, 0], f)])
    one = data_residual(vol, v + [1.0, 0, 0], f)
    assert data_residual(vol, np.asarray(both.vertices), np.asarray(both.faces)) < 0.05
    assert one > 3.0


def test_a_part_is_lacking_where_a_sample_lies_outside_the_mesh_past_half_a_voxel_plus_the_noise():
    """A sphere smaller by 0.6 voxel leaves every band sample 0.6 voxel farther out than its distance: a part of
    the data it lacks (unless the noise allows 0.2 voxel more); one larger by as much covers samples instead —
    nothing a start with more material could mend — and lacks nothing."""
    vol = _sphere_volume()
    v, f = _sphere_mesh(_R)
    e = data_errors(vol, v, f)
    assert len(e) > 1000 and not lacks_a_part(e, 0.0)
    smaller = data_errors(vol, v * (1 - 0.6 * _H / _R), f)
    assert smaller.min() > 0.5 and lacks_a_part(smaller, 0.0)
    assert not lacks_a_part(smaller, 0.2 / AGREE_NOISE_STDS)
    larger = data_errors(vol, v * (1 + 0.6 * _H / _R), f)
    assert larger.max() < -0.5 and not lacks_a_part(larger, 0.0)
    assert lacks_a_part(np.zeros(0), 1.0)
    assert AGREE_VOXELS == 0.5


def test_pick_keeps_the_usual_start_unless_another_is_clearly_better():
    u = 0.1
    assert pick({"usual": u, "carved": u * (1 - PREFER_USUAL / 2), "carved_level": u}) == "usual"
    assert pick({"usual": u, "carved": u * 0.5, "carved_level": u * 0.6}) == "carved"
    assert pick({"usual": u, "carved": u * 0.9, "carved_level": u * 0.6}) == "carved_level"
    assert pick({"usual": u, "carved": np.nan, "carved_level": u * 0.9}) == "carved_level"
    assert pick({"usual": np.nan, "carved": u}) == "carved"
    assert pick({"usual": u}) == "usual"


def test_the_choice_runs_only_where_it_can():
    vol = _sphere_volume()
    cfg = ShapeGradient().config
    assert start_candidates(cfg, vol) == CANDIDATES
    assert CANDIDATES[0] == ("usual", {})
    assert start_candidates({**cfg, "start_choice": "off"}, vol) == ()
    assert start_candidates({**cfg, "init": "sphere"}, vol) == ()
    mask = Volume(vol.values, vol.origin, vol.spacing, kind="mask", raw=(vol.values < 0).astype(float), level=0.5)
    assert start_candidates(cfg, mask) == ()
    big = Volume(np.ones((130, 130, 130)), [0.0] * 3, 1.0)           # refines to 259³ > 2²⁴ samples
    assert start_candidates(cfg, big) == ()
    assert all(set(start) <= set(USUAL_START) for _, start in CANDIDATES)
    assert start_settings({"start_level": 0.25}) == {**USUAL_START, "start_level": 0.25}
    with pytest.raises(ValueError, match="unknown start settings"):
        start_settings({"hold": True})


def test_the_choice_keeps_a_limb_only_the_carved_start_has():
    vol, tip = far_limb_volume()
    rec = ShapeGradient().reconstruct(vol)
    choice = rec.info["start_choice"]
    res = {k: v["residual_voxels"] for k, v in choice["candidates"].items()}
    assert set(res) == {name for name, _ in CANDIDATES}
    assert choice["candidates"]["usual"]["largest_error_voxels"] > 4.0       # the samples around the lost limb
    assert choice["chosen"] != "usual" and res[choice["chosen"]] == min(res.values())
    assert abs(tip - rec.mesh.vertices[:, 0].max()) / vol.h < 1.0
    assert rec.mesh.is_watertight and rec.mesh.euler_number == 2
    usual = ShapeGradient(start_choice="off", reach_samples=False).reconstruct(vol)
    assert "start_choice" not in usual.info
    assert (tip - usual.mesh.vertices[:, 0].max()) / vol.h > 4.0              # the usual start loses the limb


def test_the_choice_tries_no_other_start_where_the_usual_result_agrees_with_every_sample():
    rec = ShapeGradient().reconstruct(_sphere_volume(24))
    choice = rec.info["start_choice"]
    assert choice["chosen"] == "usual" and list(choice["candidates"]) == ["usual"]
    assert choice["candidates"]["usual"]["largest_error_voxels"] <= AGREE_VOXELS


def test_pick_without_a_usual_result_takes_the_least_residual():
    assert pick({"carved": 0.3, "carved_level": 0.2}) == "carved_level"
    assert pick({"carved": 0.3, "carved_level": np.nan}) == "carved"


def test_a_failed_usual_flow_leaves_the_choice_to_the_carved_starts(monkeypatch):
    """The usual start's flow fails (here: made to); the carved ones still run and one is kept, the failure
    recorded; when every start fails the usual one's error is the method's; an input error ends it at once."""
    from methods import ReconstructionFailed
    from phantoms import InputError

    vol, tip = far_limb_volume()
    method = ShapeGradient()
    real = ShapeGradient.prepare

    def usual_fails(self, volume, *, ops=None, start=None):
        if not start:
            raise ReconstructionFailed("the usual flow collapsed (test)")
        return real(self, volume, ops=ops, start=start)
    monkeypatch.setattr(ShapeGradient, "prepare", usual_fails)
    rec = method.reconstruct(vol)
    choice = rec.info["start_choice"]
    assert choice["candidates"]["usual"]["error"].startswith("the usual flow collapsed")
    assert choice["chosen"] != "usual" and abs(tip - rec.mesh.vertices[:, 0].max()) / vol.h < 1.0

    def all_fail(self, volume, *, ops=None, start=None):
        raise ReconstructionFailed("collapsed: " + ("usual" if not start else "carved"))
    monkeypatch.setattr(ShapeGradient, "prepare", all_fail)
    with pytest.raises(ReconstructionFailed, match="collapsed: usual"):
        method.reconstruct(vol)

    def bad_input(self, volume, *, ops=None, start=None):
        raise InputError("far from one genus-0 surface (test)")
    monkeypatch.setattr(ShapeGradient, "prepare", bad_input)
    with pytest.raises(InputError, match="far from"):
        method.reconstruct(vol)
