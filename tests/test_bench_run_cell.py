"""Tests of ``bench.run.cell``: :func:`run_cell` on one tiny cell (ok / failed rows, never raising),
:func:`failed_result`, :func:`build_volume` with its cache, :func:`truth_samples`, :func:`vertex_mean_curvature`
and :func:`method_info`."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import trimesh

import runner_plugins  # noqa: F401  (registers "failing" here too)
from bench.config import config_from_dict
from bench.run import Cell, CellResult, expand_grid
from bench.run.cell import (build_volume, cell_source, failed_result, method_info, run_cell, truth_samples,
                            vertex_mean_curvature)

ID_COLUMNS = ("cell_id", "phantom", "variant", "N", "noise", "seed", "method", "label")


@pytest.fixture(scope="module")
def sphere_cell() -> Cell:
    cfg = config_from_dict({"grid": {"phantoms": ["sphere"], "n": 24}, "methods": [{"name": "marching_cubes"}],
                            "metrics": {"n_samples": 2000}})
    cfg.validate()
    (cell,) = expand_grid(cfg)
    return cell


def test_run_cell_on_a_small_sphere_gives_an_ok_row_with_metrics_and_phase_times(sphere_cell):
    result = run_cell(sphere_cell)
    row = result.row.to_dict()
    assert isinstance(result, CellResult)
    assert row["status"] == "ok" and row["error"] == "" and result.traceback is None
    for key in ID_COLUMNS:
        assert key in row
    assert row["cell_id"] == sphere_cell.cell_id and row["N"] == 24
    assert row["h"] == pytest.approx(2 * 2.5 / 23)
    assert row["has_truth"] is True
    # marching cubes of a unit sphere at N = 24: one closed genus-0 surface well within a cell of the truth
    assert row["watertight"] and row["euler"] == 2 and row["components"] == 1
    assert 0 < row["hausdorff_h"] < 0.5
    assert row["iou"] > 0.9
    assert row["n_faces"] > 0 and row["stop_reason"] == "done"
    phases = row["phase_s"]
    for phase in ("volume", "setup", "method", "validity", "metrics"):
        assert phases[phase] >= 0.0
    assert any(k.startswith("metrics/") for k in phases)
    assert row["cell_s"] >= phases["metrics"] and row["cpu_s"] > 0
    art = result.artifacts
    assert art["vertices"].shape[1] == 3 and len(art["H"]) == len(art["vertices"])


def test_a_method_that_raises_gives_a_failed_row_naming_the_stage_and_never_raises(sphere_cell):
    cell = {**sphere_cell.to_dict(), "method": "failing", "label": "failing", "imports": ["runner_plugins"],
            "cell_id": "failing"}
    result = run_cell(cell)
    row = result.row.to_dict()
    assert row["status"] == "failed"
    assert row["error"].startswith("reconstruction:") and "deliberate failure" in row["error"]
    assert "RuntimeError" in result.traceback
    assert row["cell_id"] == "failing" and "cell_s" in row


def test_an_unknown_phantom_fails_in_the_volume_stage(sphere_cell):
    row = run_cell({**sphere_cell.to_dict(), "phantom": "no_such_phantom", "cell_id": "nope"}).row.to_dict()
    assert row["status"] == "failed" and row["error"].startswith("volume:")


def test_failed_result_has_the_id_columns_status_and_error(sphere_cell):
    result = failed_result(sphere_cell, "timeout", "cell time limit (1 s) exceeded")
    assert result.artifacts == {} and result.traceback is None
    row = result.row.to_dict()
    assert row["status"] == "timeout" and row["error"] == "cell time limit (1 s) exceeded"
    assert row["cell_id"] == sphere_cell.cell_id and row["method"] == "marching_cubes"


def test_cell_source_is_the_source_or_the_phantom_name(sphere_cell):
    assert cell_source(sphere_cell) == "sphere"
    assert cell_source(replace(sphere_cell, phantom="a", source="mesh:/data/a.obj")) == "mesh:/data/a.obj"


def test_build_volume_caches_the_clean_volume_and_reads_it_back(sphere_cell, tmp_path):
    ph, vol = build_volume(sphere_cell, str(tmp_path))
    assert vol.shape == (24, 24, 24)
    (cached,) = tmp_path.glob("*.npz")
    _, again = build_volume(sphere_cell, str(tmp_path))
    np.testing.assert_array_equal(again.values, vol.values)
    cached.write_bytes(b"not an npz")                          # a broken cache file is rebuilt
    _, rebuilt = build_volume(sphere_cell, str(tmp_path))
    np.testing.assert_array_equal(rebuilt.values, vol.values)


def test_truth_samples_lie_on_the_unit_sphere_and_are_cached(sphere_cell, tmp_path):
    ph, _ = build_volume(sphere_cell)
    pts = truth_samples(sphere_cell, ph, str(tmp_path))
    assert pts.shape == (2000, 3)
    np.testing.assert_allclose(np.linalg.norm(pts, axis=1), 1.0, atol=1e-6)
    np.testing.assert_array_equal(truth_samples(sphere_cell, ph, str(tmp_path)), pts)
    assert truth_samples(sphere_cell, None) is None


def test_vertex_mean_curvature_of_a_sphere_is_one_over_its_radius():
    r = 2.0
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=r)
    H = vertex_mean_curvature(mesh.vertices, mesh.faces, h=0.15)
    assert H.shape == (len(mesh.vertices),)
    np.testing.assert_allclose(np.abs(H), 1.0 / r, rtol=0.05)
    assert len(vertex_mean_curvature(np.zeros((0, 3)), np.zeros((0, 3), int), 0.1)) == 0


def test_method_info_keeps_plain_values_and_drops_the_artifact_arrays():
    info = {"iterations": np.int64(3), "energy_history": [1.0, 0.5], "snapshots": [object()], "mine": np.float32(2)}
    out = method_info(info)
    assert out == {"iterations": 3, "mine": 2.0}
    assert type(out["iterations"]) is int
    assert method_info(None) == {}


def test_small_snapshots_get_their_mean_curvature_in_the_cell_large_ones_are_left_to_the_report(monkeypatch):
    from types import SimpleNamespace

    from bench.run import cell as cell_mod

    sphere = trimesh.creation.icosphere(subdivisions=3, radius=1.5)        # 642 vertices
    v, f = np.asarray(sphere.vertices), np.asarray(sphere.faces)
    rec = SimpleNamespace(mesh=sphere, info={"snapshots": {1: 1.2 * v, 5: (v, f)}})
    art = cell_mod._artifacts(rec, 0.1)
    assert set(art["snapshot_iterations"]) == {1, 5}
    np.testing.assert_allclose(art["snap1_H"], cell_mod.vertex_mean_curvature(1.2 * v, f, 0.1), rtol=1e-5)
    assert abs(float(np.median(art["snap1_H"])) - 1 / 1.8) < 0.02               # H = 1/r of the scaled sphere
    monkeypatch.setattr(cell_mod, "SNAPSHOT_H_MAX_VERTICES", len(v) - 1)
    assert "snap1_H" not in cell_mod._artifacts(rec, 0.1)


def test_a_degraded_cell_names_its_input_kind_and_scores_the_volume_error():
    cfg = config_from_dict({"grid": {"phantoms": ["sphere"], "n": 40, "degrade": ["thick_slices@3+mask"]},
                            "methods": [{"name": "marching_cubes"}]})
    (cell,) = expand_grid(cfg)
    row = run_cell(cell).row.to_dict()
    assert row["status"] == "ok", row["error"]
    assert row["degrade"] == "thick_slices@3+mask" and row["input_kind"] == "mask"
    assert row["h"] == pytest.approx(5 / 39)                     # the in-plane spacing
    assert abs(row["volume_err_pct"]) < 10 and row["hausdorff_h"] < 3


def _ct_sphere(tmp_path):
    """A CT-like image of the unit ball: 1000 inside, 0 outside, a smooth (logistic) ramp one voxel wide across
    the boundary; and the exact sphere (a fine icosphere) as the truth."""
    import nibabel as nib

    x = np.linspace(-2, 2, 41)
    r = np.sqrt(sum(c ** 2 for c in np.meshgrid(x, x, x, indexing="ij")))
    aff = np.diag([0.1, 0.1, 0.1, 1.0])
    aff[:3, 3] = -2
    nib.save(nib.Nifti1Image((1000 / (1 + np.exp((r - 1) / 0.1))).astype(np.float32), aff), str(tmp_path / "ct.nii.gz"))
    trimesh.creation.icosphere(subdivisions=5, radius=1.0).export(str(tmp_path / "ball.obj"))
    return tmp_path / "ct.nii.gz", tmp_path / "ball.obj"


def test_an_intensity_at_a_level_keeps_the_subvoxel_boundary_and_its_fidelity_reads_distances(tmp_path):
    ct, ball = _ct_sphere(tmp_path)
    rows = {}
    for opt in ("level=500", "threshold=500"):
        cfg = config_from_dict({"grid": {"phantoms": [f"volume:{ct}?{opt}&truth={ball}"]},
                                "metrics": {"n_samples": 20000}, "methods": [{"name": "marching_cubes"}]})
        (cell,) = expand_grid(cfg)
        rows[opt] = run_cell(cell).row.to_dict()
        assert rows[opt]["status"] == "ok", rows[opt]["error"]
    level, threshold = rows["level=500"], rows["threshold=500"]
    assert level["input_kind"] == "intensity" and threshold["input_kind"] == "mask"
    assert level["mean_dist_h"] * 3 <= threshold["mean_dist_h"]        # measured: 0.019 h against 0.151 h
    # the intensity's slope at the boundary is ~2,300 per world unit: read as φ / |∇φ|, not as a distance
    assert level["phi_gradient"] > 100 and abs(threshold["phi_gradient"] - 1) < 0.1
    for k in ("sdf_rms_h", "phi_mean_h", "sign_err_pct"):
        assert np.isfinite(level[k]) and level[k] < 1.0, (k, level[k])


def test_a_label_map_with_labels_all_is_one_phantom_per_label_each_meshed_in_one_run(tmp_path):
    import nibabel as nib

    lab = np.zeros((30, 30, 30), np.int16)
    lab[3:10, 3:10, 3:10] = 1
    lab[12:20, 5:15, 5:15] = 2
    lab[5:25, 18:27, 18:27] = 5
    nib.save(nib.Nifti1Image(lab, np.eye(4)), str(tmp_path / "organs.nii.gz"))
    cfg = config_from_dict({"grid": {"phantoms": [f"volume:{tmp_path / 'organs.nii.gz'}?labels=all"]},
                            "metrics": {"n_samples": 2000}, "methods": [{"name": "marching_cubes"}]})
    cfg.validate()
    cells = expand_grid(cfg)
    assert [c.phantom for c in cells] == ["organs_label1", "organs_label2", "organs_label5"]
    for cell, label in zip(cells, (1, 2, 5)):
        row = run_cell(cell).row.to_dict()
        assert row["status"] == "ok" and row["input_kind"] == "mask", row["error"]
        assert row["n_faces"] > 0 and row["components"] == 1


def test_the_sdf_energy_reads_the_exact_clean_grid_even_where_phi_gradient_is_small():
    """The cortex under the field's protocol at N = 41: its sulci make the median |∇φ| at the zero set 0.69, so
    validity and fidelity read φ / |∇φ|; the SDF energy must still read the exact S the papers use.  Against
    every grid point (gpytoolbox) within 4 standard errors of the 8,192-point subset (1.7 % of the value)."""
    import gpytoolbox as gpy

    from methods import get_method
    from phantoms import get_phantom

    cfg = config_from_dict({"grid": {"phantoms": ["field:cortex"], "n": 41, "extent": 1.0},
                            "methods": [{"name": "marching_cubes"}], "metrics": {"n_samples": 2000}})
    cfg.validate()
    (cell,) = expand_grid(cfg)
    row = run_cell(cell).row.to_dict()
    assert row["status"] == "ok" and row["phi_gradient"] < 0.8
    vol = get_phantom("field:cortex").volume(n=41, extent=1.0)
    mesh = get_method("marching_cubes").reconstruct(vol).mesh
    U = vol.index_to_world(np.argwhere(np.ones(vol.shape, bool)))
    d = np.sqrt(gpy.squared_distance(U, np.asarray(mesh.vertices), np.asarray(mesh.faces, np.int32),
                                     use_cpp=True, use_aabb=True)[0])
    g2 = 1000 * (np.abs(vol.values.reshape(-1)) - d) ** 2
    se = g2.std() * np.sqrt((1 - 8192 / len(g2)) / 8192)
    assert se < 0.03 * g2.mean()
    assert abs(row["sdf_energy"] - g2.mean()) <= 4 * se, (row["sdf_energy"], g2.mean(), se)


# ------------------------------------------------------------------ the method's hooks: skip_reason and warm_up
def _hook_cell(sphere_cell, method: str, **params) -> dict:
    return {**sphere_cell.to_dict(), "method": method, "label": method, "params": params,
            "imports": ["hook_plugins"], "cell_id": method}


def test_a_method_declining_its_input_gives_a_skipped_row_with_its_reason_and_no_scores(sphere_cell):
    result = run_cell(_hook_cell(sphere_cell, "picky_mc"))
    row = result.row.to_dict()
    assert row["status"] == "skipped" and result.traceback is None and result.artifacts == {}
    assert row["error"] == "the grid has 24 points per axis, fewer than the 30 it needs"
    assert "hausdorff_h" not in row and "wall_s" not in row and '"min_n":30' in row["parameters"]
    assert run_cell(_hook_cell(sphere_cell, "picky_mc", min_n=20)).row.status == "ok"


def test_warm_up_runs_before_the_timed_reconstruct_and_is_not_in_wall_s(sphere_cell, monkeypatch):
    import hook_plugins

    monkeypatch.setattr(hook_plugins, "_WARMED", [])
    row = run_cell(_hook_cell(sphere_cell, "warm_mc")).row.to_dict()
    assert row["status"] == "ok", row["error"]                 # reconstruct found the method warmed up
    assert row["phase_s"]["warm_up"] >= hook_plugins.WARM_SECONDS > row["wall_s"]
    assert row["phase_s"]["method"] < hook_plugins.WARM_SECONDS


def test_a_hook_that_raises_fails_the_cell_naming_where(sphere_cell):
    warm = run_cell(_hook_cell(sphere_cell, "bad_hooks", hook="warm_raises"))
    assert warm.row.status == "failed" and warm.row.error.startswith("warm-up: RuntimeError")
    skip = run_cell(_hook_cell(sphere_cell, "bad_hooks", hook="skip_type")).row.to_dict()
    assert skip["status"] == "failed" and "skip_reason returned 3" in skip["error"]


def test_the_row_records_the_phantoms_shape_kind(sphere_cell, monkeypatch):
    """``shape_kind`` is the phantom's class attribute as it is (None where a phantom declares none): the report's
    recommendation table groups inputs by it."""
    from phantoms import get_phantom

    declared = getattr(get_phantom("sphere"), "shape_kind", None)
    assert run_cell(sphere_cell).row.to_dict()["shape_kind"] == declared
    monkeypatch.setattr(type(get_phantom("sphere")), "shape_kind", "a test kind", raising=False)
    assert run_cell(sphere_cell).row.to_dict()["shape_kind"] == "a test kind"

@pytest.mark.parametrize("kind, reason", [("collapsed", "empty mesh: zero area"),
                                          ("no_faces", "empty: the mesh has no vertices or no faces")])
def test_an_empty_or_zero_area_mesh_is_an_invalid_row_naming_why_not_a_scoring_crash(sphere_cell, kind, reason):
    result = run_cell(_hook_cell(sphere_cell, "degenerate_mesh", kind=kind))
    row = result.row.to_dict()
    assert row["status"] == "invalid" and reason in row["error"], row["error"]
    assert result.traceback is None


def test_a_methods_slow_import_is_paid_before_its_timed_reconstruct(sphere_cell, monkeypatch):
    """The library a method imports lazily (Method.imports) is imported in the warm-up, not in wall_s."""
    import sys

    monkeypatch.delitem(sys.modules, "slow_import_library", raising=False)
    row = run_cell(_hook_cell(sphere_cell, "slow_import_mc")).row.to_dict()
    import slow_import_library

    assert row["status"] == "ok", row["error"]
    assert row["phase_s"]["warm_up"] >= slow_import_library.IMPORT_SECONDS > row["wall_s"]


def test_a_label_is_read_once_per_run_and_cached_as_its_mask_rebuilding_the_same_volume(tmp_path, monkeypatch):
    """The first cell of a label stores its mask (one bit a voxel, compressed; at most 1.2× the label map's file);
    the next cells rebuild the same values, to the bit, without reading the image again."""
    import nibabel as nib

    import phantoms.user

    rng = np.random.default_rng(1)
    lab = np.zeros((60, 50, 40), np.uint8)
    lab[5:30, 5:30, 5:30] = 1
    lab[35:55, 10:45, 8:35] = 2
    lab[rng.random(lab.shape) < 0.002] = 3                      # scattered voxels: a label map's noise
    nii = tmp_path / "organs.nii.gz"
    nib.save(nib.Nifti1Image(lab, np.diag([0.8, 0.8, 1.5, 1.0])), str(nii))
    cfg = config_from_dict({"grid": {"phantoms": [f"volume:{nii}?labels=1,2&pad=1"]},
                            "metrics": {"n_samples": 2000}, "methods": [{"name": "marching_cubes"}]})
    cfg.validate()
    cache = tmp_path / "cache"
    for cell in expand_grid(cfg):
        _, fresh = build_volume(cell)                                  # no cache: the image read as ever
        _, first = build_volume(cell, str(cache))
        (stored,) = cache.glob(f"{cell.phantom}_*_mask.npz")
        assert stored.stat().st_size <= 1.2 * nii.stat().st_size
        with monkeypatch.context() as m:
            m.setattr(phantoms.user, "read_image", lambda *a, **k: pytest.fail("the image was read again"))
            ph, again = build_volume(cell, str(cache))
        for vol in (first, again):
            assert vol.kind == fresh.kind == "mask" and vol.values.dtype == fresh.values.dtype
            assert np.array_equal(vol.values, fresh.values) and np.array_equal(vol.raw, fresh.raw)
            assert np.array_equal(vol.origin, fresh.origin) and np.array_equal(vol.spacing, fresh.spacing)
        assert ph.level_set.kind == "mask" and not ph.has_truth
