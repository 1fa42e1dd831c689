"""A user's own data in a grid: NIfTI volumes in world coordinates with and without ground truth, datasets as
globs, a built-in phantom round-tripped through a file, unreadable files as failed rows, bad input as exit 2."""

from __future__ import annotations

import csv
import os
import subprocess
import sys
from pathlib import Path

import nibabel as nib
import numpy as np
import pytest
import trimesh

from _volumes import BOX_ORIGIN, BOX_SPACING, boxes_mask, write_boxes
from bench.metrics import FIDELITY_NAMES
from bench.run.cell import run_cell

REPO = Path(__file__).resolve().parent.parent
TESTS = Path(__file__).resolve().parent


def _bench(*args, cwd=REPO) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(TESTS), str(REPO)] + [p for p in [env.get("PYTHONPATH")] if p])
    env["PYTHONWARNINGS"] = "ignore"
    return subprocess.run([sys.executable, "-m", "bench", *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=600)


def _rows(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def boxes_runs(tmp_path_factory):
    """The boxes mask (spacing 0.5, 0.5, 0.8; non-zero origin) in a grid with marching cubes, the shape gradient
    and Poisson: once without truth (a TOML table phantom), once with ``truth=boxes.obj`` (a spec string)."""
    d = tmp_path_factory.mktemp("boxes")
    nii, obj = write_boxes(d)
    cfg = d / "boxes.toml"
    cfg.write_text(f'''name = "boxes"
[grid]
phantoms = [{{ volume = "{nii}" }}, "volume:{nii}?truth={obj}"]
noise = [{{ kind = "none" }}]
[[methods]]
name = "marching_cubes"
[[methods]]
name = "shape_gradient"
[[methods]]
name = "poisson"
[metrics]
n_samples = 20000
''')
    out = d / "run"
    proc = _bench("run", "--config", str(cfg), "--out", str(out), "--jobs", "2")
    assert proc.returncode == 0, proc.stderr[-3000:]
    return out, _rows(out / "results.csv"), nii, obj


def test_meshes_are_in_the_files_world_coordinates(boxes_runs):
    out, rows, _, _ = boxes_runs
    m = boxes_mask()
    idx = np.argwhere(m)
    lo = BOX_ORIGIN + (idx.min(0) - 0.5) * BOX_SPACING          # the voxel set's boundary, world units
    hi = BOX_ORIGIN + (idx.max(0) + 0.5) * BOX_SPACING
    assert len(rows) == 6 and all(r["status"] == "ok" for r in rows), [(r["label"], r["error"]) for r in rows]
    for r in rows:
        with np.load(out / "cells" / f"{r['cell_id']}.npz") as z:
            v = z["vertices"]
        assert np.all(np.abs(v.min(0) - lo) <= BOX_SPACING) and np.all(np.abs(v.max(0) - hi) <= BOX_SPACING), r["label"]
        assert int(r["N"]) == max(m.shape) and float(r["h"]) == pytest.approx(0.5)


def test_without_truth_the_report_says_so_and_the_fidelity_metrics_rank(boxes_runs):
    out, rows, nii, _ = boxes_runs
    plain = [r for r in rows if r["phantom"] == f"volume:{nii}"]
    assert len(plain) == 3 and all(r["has_truth"] == "False" and r["hausdorff"] == "" for r in plain)
    for k in FIDELITY_NAMES:
        vals = [float(r[k]) for r in plain]
        assert all(np.isfinite(vals)), k
    assert len({round(float(r["sdf_rms_h"]), 6) for r in plain}) == 3       # the methods are told apart
    page = (out / "index.html").read_text()
    assert page.count("no ground truth: data fidelity and mesh quality only") == 1   # one table has no truth


def test_with_the_exact_surface_as_truth_marching_cubes_is_within_a_voxel(boxes_runs):
    _, rows, nii, obj = boxes_runs
    truth = {r["label"]: r for r in rows if r["phantom"] == f"volume:{nii}?truth={obj}"}
    assert all(r["has_truth"] == "True" for r in truth.values())
    assert float(truth["marching_cubes"]["hausdorff"]) <= BOX_SPACING.max()
    for r in truth.values():
        assert np.isfinite(float(r["mean_dist"])) and np.isfinite(float(r["fscore@h"]))


@pytest.mark.heavy
def test_brain_mri_through_a_file_scores_like_the_builtin(tmp_path):
    """The built-in brain_mri volume written as NIfTI-2 (double-precision affine) and its truth mesh as PLY: the
    same cells give the same metrics."""
    from phantoms import get_phantom

    ph = get_phantom("brain_mri")
    vol = ph.volume(n=40)
    aff = np.diag([*vol.spacing, 1.0])
    aff[:3, 3] = vol.origin
    nib.save(nib.Nifti2Image(vol.values, aff), str(tmp_path / "brain.nii"))
    trimesh.Trimesh(ph.vertices, ph.faces, process=False).export(str(tmp_path / "brain.ply"))
    base = {"variant": "sdf", "extent": 2.5, "noise": "none", "snr_requested": None, "seed": 0,
            "method": "marching_cubes", "label": "marching_cubes", "params": {}, "n_samples": 20000,
            "imports": [], "cell_id": "c"}
    a = run_cell({**base, "phantom": "brain_mri", "n": 40}).row.to_dict()
    truth = f"volume:{tmp_path / 'brain.nii'}?truth={tmp_path / 'brain.ply'}"
    b = run_cell({**base, "phantom": truth, "n": 0}).row.to_dict()
    c = run_cell({**base, "phantom": f"volume:{tmp_path / 'brain.nii'}", "n": 0}).row.to_dict()
    assert a["status"] == b["status"] == c["status"] == "ok" and b["N"] == 40
    for k in FIDELITY_NAMES + ["euler", "min_angle_deg", "self_intersections"]:
        assert b[k] == a[k] and c[k] == a[k], k
    assert b["roughness_deg"] == a["roughness_deg"]       # without a truth no crease is left out
    for k in ["hausdorff", "mean_dist", "fscore@h", "iou"]:   # PLY stores the truth's vertices as float32
        assert b[k] == pytest.approx(a[k], rel=1e-3), k
    assert "hausdorff" not in c and c["has_truth"] is False


@pytest.mark.heavy
def test_a_mesh_glob_is_a_dataset_and_a_corrupt_file_fails_only_its_cells(tmp_path):
    data = tmp_path / "shapes"
    data.mkdir()
    trimesh.creation.icosphere(3, radius=1.0).export(str(data / "ball.obj"))
    trimesh.creation.capsule(height=1.0, radius=0.5).export(str(data / "capsule.obj"))
    (data / "broken.obj").write_text("v 0 0 0\nv 1 0 0\nf 1 2 9 garbage\n")
    out = tmp_path / "run"
    proc = _bench("run", "--phantoms", f"mesh:{data}/*.obj", "--noise", "none", "--n", "24",
                  "--method", "marching_cubes", "--n-samples", "5000", "--out", str(out), "--jobs", "2")
    assert proc.returncode == 0, proc.stderr[-3000:]
    rows = {r["phantom"]: r for r in _rows(out / "results.csv")}
    assert sorted(rows) == ["ball", "broken", "capsule"]
    assert rows["ball"]["status"] == rows["capsule"]["status"] == "ok"
    assert rows["broken"]["status"] == "failed" and "broken.obj" in rows["broken"]["error"]
    assert rows["ball"]["source"] == f"mesh:{data}/ball.obj"
    empty = _bench("run", "--phantoms", f"mesh:{data}/*.stl", "--noise", "none", "--method", "marching_cubes",
                   "--out", str(tmp_path / "r2"))
    assert empty.returncode == 2 and "no file matches the pattern" in empty.stderr
    assert "Traceback" not in empty.stderr and len(empty.stderr.strip().splitlines()) == 1


@pytest.mark.heavy   # end to end, ~10 s: run by .ci/run's second pytest
def test_an_unreadable_volume_is_a_failed_row_in_a_grid(tmp_path):
    (tmp_path / "cut.nii.gz").write_bytes(b"\x1f\x8b not really")
    nii, _ = write_boxes(tmp_path)
    out = tmp_path / "run"
    proc = _bench("run", "--phantoms", f"volume:{tmp_path}/*.nii.gz", "--noise", "none", "--method",
                  "marching_cubes", "--n-samples", "5000", "--out", str(out), "--jobs", "1")
    assert proc.returncode == 0, proc.stderr[-3000:]
    rows = {r["phantom"]: r for r in _rows(out / "results.csv")}
    assert rows["boxes"]["status"] == "ok"
    assert rows["cut"]["status"] == "failed" and "cut.nii.gz: cannot read" in rows["cut"]["error"]


@pytest.mark.parametrize("args, message", [
    (["info", "{d}/four.nii.gz"], "a 4-D image"),
    (["info", "volume:{d}/labels.nii.gz?label=9"], "label 9 does not occur"),
    (["reconstruct", "volume:{d}/labels.nii.gz?threshold=50", "--method", "marching_cubes", "-o", "{d}/o.ply"],
     "threshold 50 leaves no voxel inside"),
    (["run", "--phantoms", "volume:{d}/missing.nii.gz", "--noise", "none", "--out", "{d}/r"], "no such volume file"),
    (["run", "--phantoms", "volume:{d}/labels.nii.gz", "--out", "{d}/r"], "has no paper SNR; give the SNR in dB"),
])
def test_bad_input_is_one_line_and_exit_2(tmp_path, args, message):
    nib.save(nib.Nifti1Image(np.zeros((4, 4, 4, 2), np.float32), np.eye(4)), str(tmp_path / "four.nii.gz"))
    labels = np.zeros((10, 10, 10), np.int16)
    labels[3:7, 3:7, 3:7] = 2
    nib.save(nib.Nifti1Image(labels, np.eye(4)), str(tmp_path / "labels.nii.gz"))
    proc = _bench(*[a.format(d=tmp_path) for a in args])
    assert proc.returncode == 2, proc.stderr
    assert message in proc.stderr and "Traceback" not in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1



def _two_boxes(folder: Path) -> tuple[Path, Path]:
    """A NIfTI mask of two boxes four voxels apart (the boxes' spacing and origin), and an OBJ with the exact surface
    of the first box only: a 'pipeline export' that dropped a part."""
    import nibabel as nib

    from _volumes import voxel_surface

    m = np.zeros((22, 14, 12), bool)
    m[2:9, 3:11, 3:9] = True
    m[13:20, 3:11, 3:9] = True
    aff = np.diag([*BOX_SPACING, 1.0])
    aff[:3, 3] = BOX_ORIGIN
    nii = folder / "two_boxes.nii.gz"
    nib.save(nib.Nifti1Image(m.astype(np.uint8), aff), str(nii))
    first = m.copy()
    first[11:] = False
    v, f = voxel_surface(first, BOX_ORIGIN, BOX_SPACING)
    obj = folder / "first_box.obj"
    trimesh.Trimesh(v, f, process=False).export(str(obj))
    return nii, obj


def test_a_dropped_part_of_a_user_volume_is_flagged_and_its_no_truth_table_says_what(tmp_path):
    """Without ground truth: the export's row carries ``topology_vs_data`` with "dropped parts: 1 of 2 in data", it
    is not usable, and the no-truth summary table shows the flag's badge and the detail; marching cubes of the same
    mask is not flagged."""
    import pandas as pd

    from bench.metrics.flags import is_usable
    from bench.report.tables import NO_TRUTH_NOTE, summary_tables

    nii, obj = _two_boxes(tmp_path)
    base = {"phantom": f"volume:{nii}", "n": 0, "variant": "sdf", "extent": 2.5, "noise": "none",
            "snr_requested": None, "seed": 0, "n_samples": 5000, "imports": []}
    rows = {}
    for label, method, params in (("marching_cubes", "marching_cubes", {}),
                                  ("export", "mesh_file", {"path": str(obj)})):
        rows[label] = run_cell({**base, "method": method, "label": label, "params": params,
                                "cell_id": label}).row.to_dict()
    export, mc = rows["export"], rows["marching_cubes"]
    assert export["status"] == mc["status"] == "ok", (export["error"], mc["error"])
    assert "topology_vs_data" in export["flags"].split(";") and not is_usable(export)
    assert export["topology_vs_data_detail"] == "dropped parts: 1 of 2 in data"
    assert export["data_parts"] == 2 and export["topology_diffs"] == 1
    assert "topology_vs_data" not in mc["flags"] and mc["topology_vs_data_detail"] == "" and is_usable(mc)
    (table,) = summary_tables(pd.DataFrame(list(rows.values())))
    assert table["note"] == NO_TRUTH_NOTE
    assert ">topology_vs_data</span>" in table["html"] and "dropped parts: 1 of 2 in data" in table["html"]


@pytest.mark.heavy
def test_a_mesh_that_drops_a_part_of_a_user_volume_is_flagged_in_its_no_truth_table(tmp_path):
    """The same through ``python -m bench run`` and its report: results.csv holds the flag and its detail, the
    report's no-truth table shows both."""
    nii, obj = _two_boxes(tmp_path)
    cfg = tmp_path / "two_boxes.toml"
    cfg.write_text(f'''name = "two_boxes"
[grid]
phantoms = [{{ volume = "{nii}" }}]
noise = [{{ kind = "none" }}]
[[methods]]
name = "marching_cubes"
[[methods]]
name = "mesh_file"
label = "export"
params = {{ path = "{obj}" }}
[metrics]
n_samples = 5000
''')
    out = tmp_path / "run"
    proc = _bench("run", "--config", str(cfg), "--out", str(out), "--jobs", "1")
    assert proc.returncode == 0, proc.stderr[-3000:]
    rows = {r["label"]: r for r in _rows(out / "results.csv")}
    assert rows["export"]["status"] == "ok" and rows["marching_cubes"]["status"] == "ok", rows
    assert "topology_vs_data" in rows["export"]["flags"].split(";")
    assert rows["export"]["topology_vs_data_detail"] == "dropped parts: 1 of 2 in data"
    assert "topology_vs_data" not in rows["marching_cubes"]["flags"] and not rows["marching_cubes"][
        "topology_vs_data_detail"]
    assert rows["export"]["data_parts"] == "2" and rows["export"]["topology_diffs"] == "1"
    page = (out / "index.html").read_text()
    table = page[page.index("no ground truth: data fidelity and mesh quality only"):]
    assert 'badge-flag" title="the mesh&#x27;s parts' in table and ">topology_vs_data</span>" in table
    assert "dropped parts: 1 of 2 in data" in table
