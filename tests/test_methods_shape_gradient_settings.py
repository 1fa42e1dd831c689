"""FlowSettings: the shape-gradient flow's settings, resolved once from the Params and the volume
(methods/shape_gradient/settings.py), and ShapeGradientFlow reading them (methods/shape_gradient/flow.py)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from methods.shape_gradient import ShapeGradient, ShapeGradientFlow
from methods.shape_gradient.choose import USUAL_START, start_settings
from methods.shape_gradient.settings import FlowSettings, Stage
from phantoms import InputError, add_noise, get_phantom

#: the keys info['parameters'] carries beyond the Params: the values decided from the volume
DERIVED = ["stages", "s_world", "join_below_used", "remesh_start", "presmooth_used", "noise_variance",
           "start_smooth_used", "polish_used", "projection_used", "sign_guard_used"]


def resolve(method: ShapeGradient, *, clean: bool = True, noise: float = 0.0, h: float = 0.1,
            remesh_start: bool = True, kind: str = "sdf") -> FlowSettings:
    return FlowSettings.resolve({**method.config, **start_settings()}, h=h, clean=clean, noise=noise, presmooth=0.0,
                                start_smooth=0.0, join_below=0.5 if clean else 0.0, remesh_start=remesh_start,
                                kind=kind)


def test_the_defaults_are_the_params_defaults():
    """What the flow reads is what the Params document: the guard and the sign guard on, the direct fields
    equal to the parameters' defaults."""
    m = ShapeGradient()
    st = resolve(m)
    assert st.guard is True and st.sign_guard is True
    for name in ("alpha", "gradient", "curvature", "max_move", "precondition", "relax", "max_iter", "tol",
                 "move_tol", "remesh_every"):
        assert getattr(st, name) == ShapeGradient.params[name].default, name
    assert st.snapshots == (1, 50, 100)


def test_every_parameter_given_reaches_the_settings():
    m = ShapeGradient(alpha=2.0, gradient="paper", curvature="paper", max_move=0.5, precondition="none", s=8.0,
                      relax=0.0, max_iter=7, tol=0.0, move_tol=0.0, remesh_every=0, guard=False, snapshots="2,4")
    st = resolve(m, h=0.5)
    assert (st.alpha, st.gradient, st.curvature, st.max_move) == (2.0, "paper", "paper", 0.5)
    assert (st.precondition, st.relax, st.max_iter, st.tol, st.move_tol) == ("none", 0.0, 7, 0.0, 0.0)
    assert (st.remesh_every, st.guard) == (0, False)
    assert st.s_world == 8.0 * 0.5 ** 2 and st.snapshots == (2, 4)


def test_auto_values_follow_the_volume():
    """beta, polish, projection, sign guard and the noise term are decided by clean / noisy, once."""
    clean, noisy = resolve(ShapeGradient()), resolve(ShapeGradient(), clean=False, noise=0.03)
    assert (clean.beta, clean.polish, clean.projection, clean.sign_guard) == (1.0, True, True, True)
    assert (noisy.beta, noisy.polish, noisy.projection, noisy.sign_guard) == (0.01, False, False, False)
    assert clean.noise_variance == 0.0 and noisy.noise_variance == pytest.approx((2 / 3) ** 3 * 0.03 ** 2)
    assert resolve(ShapeGradient(unbias=False), clean=False, noise=0.03).noise_variance == 0.0
    assert resolve(ShapeGradient(polish="on", projection="on"), clean=False).polish is True
    assert resolve(ShapeGradient(), remesh_start=False).sign_guard is False       # no genus-0 start: off
    assert resolve(ShapeGradient(sign_guard=False)).sign_guard is False


def test_one_stage_runs_the_configured_beta_and_edge_length():
    assert resolve(ShapeGradient(edge_length=0.7)).stages == (Stage(1.0, 0.7),)
    assert resolve(ShapeGradient(beta=0.5, edge_length=0.5)).stages == (Stage(0.5, 0.5),)


def test_the_settings_are_frozen_and_the_reported_parameters_a_copy():
    st = resolve(ShapeGradient())
    with pytest.raises(dataclasses.FrozenInstanceError):
        st.guard = False
    reported = st.reported_parameters()
    assert list(reported) == list(ShapeGradient.params) + list(USUAL_START) + DERIVED     # the start's too
    assert reported["beta"] == 1.0 and reported["stages"] == [{"beta": 1.0, "edge_length": 0.5}]
    reported["stages"][0]["beta"] = 9.0
    assert st.reported_parameters()["stages"][0]["beta"] == 1.0


def test_prepare_hands_the_flow_its_settings():
    """ShapeGradient.prepare resolves the settings from the volume; the flow runs on them and reports them."""
    vol = get_phantom("sphere").volume(n=24)
    flow = ShapeGradient(max_iter=3, guard=False).prepare(vol)
    assert isinstance(flow, ShapeGradientFlow) and isinstance(flow.settings, FlowSettings)
    assert flow.settings.guard is False and flow.settings.beta == 1.0
    rec = flow.run().result()
    assert rec.info["iterations"] <= 3 and rec.info["parameters"] == flow.settings.reported_parameters()
    assert rec.info["parameters"]["guard"] is False and rec.info["beta_used"] == 1.0
    noisy, _ = add_noise(vol, "gaussian", 20.0, seed=0)
    st = ShapeGradient(max_iter=1).prepare(noisy).settings
    assert st.beta == 0.01 and st.polish is False and st.noise_variance > 0
    assert np.isclose(st.s_world, 18.0 * vol.h ** 2)


def test_auto_edge_length_is_a_voxel_on_a_mask_and_half_a_voxel_on_a_level_set():
    from phantoms.degrade import degrade

    ph = get_phantom("sphere")
    for vol, edge in ((degrade(ph, "mask", 32), 1.0), (degrade(ph, "partial_volume", 32), 0.5),
                      (ph.volume(n=32), 0.5)):
        rec = ShapeGradient(max_iter=2).reconstruct(vol)
        assert rec.info["parameters"]["stages"][0]["edge_length"] == edge
    assert resolve(ShapeGradient(edge_length=0.8), kind="mask").stages[0].edge_length == 0.8   # a number wins
    with pytest.raises(InputError, match="edge_length"):
        ShapeGradient(edge_length=0.05)


def test_auto_edge_length_follows_the_kind_and_grows_with_the_noise():
    from methods.shape_gradient.settings import (AUTO_EDGE_VOXELS, NOISY_EDGE_MAX_VOXELS, NOISY_EDGE_PER_STD,
                                                 edge_length_voxels)

    base = AUTO_EDGE_VOXELS["other"]
    assert edge_length_voxels("auto", "sdf") == base == edge_length_voxels("auto", "sdf", 0.0)
    assert edge_length_voxels("auto", "mask", 0.3) == AUTO_EDGE_VOXELS["mask"]          # a mask: its own length
    assert edge_length_voxels("auto", "sdf", 0.1) == base                               # 3.5 × 0.1 < 0.5
    mid = 0.18
    assert edge_length_voxels("auto", "sdf", mid) == pytest.approx(NOISY_EDGE_PER_STD * mid)
    assert edge_length_voxels("auto", "intensity", 1.0) == NOISY_EDGE_MAX_VOXELS        # capped
    assert edge_length_voxels(0.35, "sdf", 1.0) == 0.35                                 # a number is kept


def test_a_clean_flow_skips_the_remeshes_it_does_not_need_and_a_noisy_one_does_not():
    from methods.shape_gradient import ShapeGradient
    from phantoms import get_phantom
    from phantoms.noise import add_noise

    vol = get_phantom("ellipsoid").volume(n=40)
    clean = ShapeGradient(start_choice="off", tol=0, move_tol=0, max_iter=12).reconstruct(vol).info
    assert clean["remesh_skipped"] + clean["remesh_touched_up"] >= 1
    assert len(clean["remeshes"]) + clean["remesh_skipped"] + clean["remesh_touched_up"] == 3     # 0, 5, 10
    noisy, _ = add_noise(vol, "gaussian", 40.0, seed=0)
    info = ShapeGradient(start_choice="off", tol=0, move_tol=0, max_iter=12).reconstruct(noisy).info
    assert info["remesh_skipped"] == info["remesh_touched_up"] == 0 and [it for it, _ in info["remeshes"]] == [0, 5, 10]
