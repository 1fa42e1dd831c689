"""bench.run.grid: a config's cells, sweeps and per-phantom parameters, stable ids; the shipped configs' grids."""

from __future__ import annotations

import json

from bench.config import CONFIG_DIR, builtin_config, config_from_dict, load_config
import pytest

from bench.run.grid import cell_id, expand_grid
from phantoms import InputError


def test_grid_expansion_sweeps_overrides_and_stable_ids():
    cfg = config_from_dict({
        "grid": {"phantoms": ["sphere", "fused_spheres"], "n": [32, 48], "seeds": [0, 1],
                 "noise": [{"kind": "none"}, {"kind": "gaussian", "snr": [30, "paper"]}]},
        "methods": [{"name": "marching_cubes", "sweep": {"step_size": [1, 2]}},
                    {"name": "mc_taubin", "label": "taubin", "phantom_params": {"fused_spheres": {"iterations": 3}}}],
    })
    cfg.validate()
    cells = expand_grid(cfg)
    # 2 phantoms x 2 N x (1 clean seed + 2 SNRs x 2 seeds) x (2 sweep values + 1) = 60
    assert len(cells) == 60
    assert len({c.cell_id for c in cells}) == 60
    assert {c.label for c in cells} == {"marching_cubes[step_size=1]", "marching_cubes[step_size=2]", "taubin"}
    fs = [c for c in cells if c.phantom == "fused_spheres" and c.label == "taubin"]
    assert all(c.params == {"iterations": 3} for c in fs)
    snrs = {c.snr_requested for c in cells if c.phantom == "fused_spheres"}
    assert snrs == {None, 30.0, 43.2}
    assert [c.cell_id for c in expand_grid(cfg)] == [c.cell_id for c in cells]  # stable
    again = config_from_dict(json.loads(json.dumps(cfg.to_dict())))  # what run folders keep (config.json)
    assert [c.cell_id for c in expand_grid(again)] == [c.cell_id for c in cells]


def test_paper_config_is_the_paper_grid():
    cfg = builtin_config("paper")
    assert cfg.phantoms == ["sphere", "ellipsoid", "fused_spheres", "cylinder"]
    assert cfg.n == [96] and cfg.seeds == [0] and cfg.variants == ["sdf"]
    assert [n.kind for n in cfg.noise] == ["none", "gaussian", "uniform"]
    labels = [lab for m in cfg.methods for lab, _ in m.instances()]
    assert labels == ["shape_gradient[paper]", "shape_gradient[paper,beta=0]", "shape_gradient[paper+fixes]",
                      "shape_gradient[paper+fixes,beta=0]", "shape_gradient", "marching_cubes", "distmesh"]
    assert cfg.methods[0].params["preset"] == "paper" and cfg.methods[1].params["beta"] == 0
    assert cfg.methods[2].params["preset"] == "paper+fixes" and cfg.methods[4].params == {}
    # β = 1 on every noise setting, the β = 0 ablations clean, the suite default clean and Gaussian
    assert len(expand_grid(cfg)) == 4 * (3 + 1 + 3 + 1 + 2 + 2 * 3)


def test_scale_config_is_48_cells_of_the_baselines():
    cfg = load_config(CONFIG_DIR / "scale48.toml")
    cells = expand_grid(cfg)
    assert len(cells) == 48 and {c.method for c in cells} == {"marching_cubes", "mc_taubin", "distmesh", "poisson"}
    assert {c.n for c in cells} == {48}


def test_real_tier_config_runs_the_fine_segmentations_on_their_own_grid():
    cfg = load_config(CONFIG_DIR / "real_tier.toml")
    cfg.validate()
    cells = expand_grid(cfg)
    # 2 segmentations x 6 coarse inputs x 7 methods, each at N = 0: the phantom's own grid, not grid.n
    assert len(cells) == 2 * 6 * 7 and {c.n for c in cells} == {0}
    assert {c.degrade for c in cells} == {f"{k}+{kind}" for k in ("downsample@2", "downsample@3", "thick_slices@3")
                                          for kind in ("mask", "partial_volume")}
    mixed = config_from_dict({"grid": {"phantoms": ["sphere", "mni_wm"], "n": [32, 48]},
                              "methods": [{"name": "marching_cubes"}]})
    assert sorted((c.phantom, c.n) for c in expand_grid(mixed)) == [("mni_wm", 0), ("sphere", 32), ("sphere", 48)]

def test_cell_id_names_the_cell_and_hashes_every_parameter():
    cfg = builtin_config("quick")
    cell = expand_grid(cfg)[0]
    cid = cell_id(cell)
    assert cid.startswith("sphere_sdf_n48_none_s0_shape_gradient_")
    other = dict(cell.to_dict(), params={**cell.params, "alpha": 4.0})
    assert cell_id(other) != cid and cell_id(other).rsplit("_", 1)[0] == cid.rsplit("_", 1)[0]


def test_vary_one_at_a_time_sweeps_noise_at_the_first_n_and_n_at_the_first_noise():
    from bench.config import config_from_dict

    grid = {"phantoms": ["sphere"], "n": [64, 32, 48], "noise": ["none", "gaussian@40", "gaussian@20"]}
    full = config_from_dict({"grid": grid, "methods": [{"name": "marching_cubes"}]})
    one = config_from_dict({"grid": dict(grid, vary="one_at_a_time"), "methods": [{"name": "marching_cubes"}]})
    pairs = [(c.n, c.noise, c.snr_requested) for c in expand_grid(one)]
    assert pairs == [(64, "none", None), (64, "gaussian", 40.0), (64, "gaussian", 20.0), (32, "none", None),
                     (48, "none", None)]
    assert len(expand_grid(full)) == 9
    # the cells of the sweep are cells of the full product (same ids): results are comparable across configs
    assert {c.cell_id for c in expand_grid(one)} <= {c.cell_id for c in expand_grid(full)}
    assert config_from_dict(one.to_dict()).vary == "one_at_a_time"
    with pytest.raises(InputError, match="grid.vary"):
        config_from_dict({"grid": dict(grid, vary="sometimes"), "methods": [{"name": "marching_cubes"}]})


def test_user_volumes_run_native_once_and_a_changed_file_changes_the_cell_ids(tmp_path):
    """A volume phantom runs on its native grid (N = 0 in the cell: one N whatever grid.n says) unless
    resample=yes; a glob names each file by its stem; editing a file gives its cells new identities."""
    import os

    import numpy as np

    for name in ("a", "b"):
        np.save(tmp_path / f"{name}.npy", np.pad(np.ones((4, 4, 4), np.uint8), 2))
    cfg = config_from_dict({
        "grid": {"phantoms": [f"volume:{tmp_path}/*.npy", {"volume": str(tmp_path / "a.npy"), "resample": True}],
                 "n": [16, 24], "noise": [{"kind": "none"}]},
        "methods": [{"name": "marching_cubes"}],
    })
    cfg.validate()
    cells = expand_grid(cfg)
    assert [(c.phantom, c.n) for c in cells] == [("a", 0), ("b", 0), (f"volume:{tmp_path / 'a.npy'}?resample=yes", 16),
                                                       (f"volume:{tmp_path / 'a.npy'}?resample=yes", 24)]
    assert cells[0].source == f"volume:{tmp_path / 'a.npy'}"
    st = os.stat(tmp_path / "b.npy")
    os.utime(tmp_path / "b.npy", ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    again = expand_grid(cfg)
    assert again[0].cell_id == cells[0].cell_id and again[1].cell_id != cells[1].cell_id


def test_degradations_are_an_axis_beside_noise_with_their_own_ids():
    base = {"grid": {"phantoms": ["sphere"], "n": 32, "seeds": [0, 1],
                     "noise": [{"kind": "none"}, {"kind": "gaussian", "snr": 30}]},
            "methods": [{"name": "marching_cubes"}]}
    plain = expand_grid(config_from_dict(base))
    base["grid"]["degrade"] = ["none", "mask", "label_noise@0.1+mask"]
    cells = expand_grid(config_from_dict(base))
    assert [c.cell_id for c in cells[:len(plain)]] == [c.cell_id for c in plain]   # undegraded ids unchanged
    extra = cells[len(plain):]
    # a degradation runs without noise; only label noise is random, so only it runs every seed
    assert [(c.degrade, c.noise, c.seed) for c in extra] == [("mask", "none", 0), ("mask+label_noise@0.1", "none", 0),
                                                             ("mask+label_noise@0.1", "none", 1)]
    assert "_mask_" in extra[0].cell_id and len({c.cell_id for c in cells}) == len(cells)
    with pytest.raises(InputError, match="grid.degrade: .*unknown step 'maks'"):
        config_from_dict({**base, "grid": {**base["grid"], "degrade": ["maks"]}})


def test_a_degradation_runs_as_asked_to_the_last_digit():
    from phantoms.degrade import parse_degradation

    asked = ["blur@1.23456789+mask", "blur@1e6+partial_volume"]
    cfg = config_from_dict({"grid": {"phantoms": ["sphere"], "n": 16, "degrade": asked},
                            "methods": [{"name": "marching_cubes"}]})
    cells = expand_grid(cfg)
    assert [parse_degradation(c.degrade) for c in cells] == [parse_degradation(a) for a in asked]
    assert "blur_1.23456789" in cells[0].cell_id and "blur_1000000" in cells[1].cell_id
