"""methods/mesh_file.py: a surface exported elsewhere, entered as a row and scored like the others."""

import numpy as np
import pytest
import trimesh

from bench.config import config_from_dict
from bench.run import expand_grid
from bench.run.cell import run_cell
from methods import get_method
from phantoms import InputError, get_phantom


def test_an_exported_surface_is_a_row_scored_like_the_others(tmp_path):
    exports = tmp_path / "exports"
    exports.mkdir()
    trimesh.creation.icosphere(subdivisions=4, radius=1.0).export(str(exports / "sphere.stl"))
    cfg = config_from_dict({"grid": {"phantoms": ["sphere", "ellipsoid"], "n": 32},
                            "metrics": {"n_samples": 5000},
                            "methods": [{"name": "mesh_file", "label": "slicer_export",
                                         "params": {"path": str(exports / "{phantom}.stl")}},
                                        {"name": "marching_cubes"}]})
    cfg.validate()
    rows = {(c.phantom, c.label): run_cell(c).row.to_dict() for c in expand_grid(cfg)}
    ok = rows["sphere", "slicer_export"]
    assert ok["status"] == "ok", ok["error"]
    assert ok["hausdorff_h"] < 0.2 and abs(ok["volume_err_pct"]) < 1      # an icosphere of the unit sphere
    missing = rows["ellipsoid", "slicer_export"]
    assert missing["status"] == "failed" and f"no such mesh file '{exports / 'ellipsoid.stl'}'" in missing["error"]
    assert rows["ellipsoid", "marching_cubes"]["status"] == "ok"


def test_an_open_or_unreadable_surface_is_one_line(tmp_path):
    box = trimesh.creation.box(extents=(1, 1, 1))
    trimesh.Trimesh(box.vertices, box.faces[:-1]).export(str(tmp_path / "open.stl"))
    (tmp_path / "junk.stl").write_text("not a mesh")
    vol = get_phantom("sphere").volume(n=16)
    for path, words in ((tmp_path / "open.stl", "is not a closed mesh"), (tmp_path / "nope.stl", "no such mesh file"),
                        (tmp_path / "junk.stl", "holds no triangles"), ("", "needs path=FILE")):
        with pytest.raises(InputError) as err:
            get_method("mesh_file", path=str(path)).reconstruct(vol)
        assert words in str(err.value) and "\n" not in str(err.value), str(err.value)
    assert np.isfinite(vol.h)


def test_phantom_in_the_path_is_the_name_a_user_sees(tmp_path, monkeypatch):
    """``{phantom}`` is a single ``volume:`` file's stem (not its whole spec), a glob's file stem, a ``labels=``
    phantom's ``STEM_labelL``: ``--add-method x=mesh_file:path=exports/{phantom}.stl`` with one volume file reads
    ``exports/STEM.stl``, and its row is scored."""
    import csv

    import nibabel as nib

    from _volumes import boxes_mask, voxel_surface
    from bench.cli import main

    monkeypatch.chdir(tmp_path)
    m = boxes_mask()
    nib.save(nib.Nifti1Image(m.astype(np.uint8), np.eye(4)), "seg.nii.gz")
    (tmp_path / "exports").mkdir()
    v, f = voxel_surface(m, np.zeros(3), np.ones(3))
    trimesh.Trimesh(v, f, process=False).export("exports/seg.stl")
    code = main(["run", "--phantoms", "volume:seg.nii.gz?pad=1", "--method", "x=mesh_file:path=exports/{phantom}.stl",
                 "--noise", "none", "--n-samples", "2000", "--jobs", "1", "--no-report", "--out", "run"])
    assert code == 0
    rows = list(csv.DictReader(open(tmp_path / "run" / "results.csv")))
    assert [(r["label"], r["status"]) for r in rows] == [("x", "ok")], rows
    specs = ["volume:seg.nii.gz?pad=1", "volume:*.nii.gz?label=1", "volume:seg.nii.gz?labels=all"]
    cfg = config_from_dict({"grid": {"phantoms": specs[2:], "n": 16},
                            "methods": [{"name": "mesh_file", "params": {"path": "exports/{phantom}.stl"}}]})
    assert {c.params["path"] for c in expand_grid(cfg)} == {"exports/seg_label1.stl"}
    cfg = config_from_dict({"grid": {"phantoms": specs[1:2], "n": 16},
                            "methods": [{"name": "mesh_file", "params": {"path": "exports/{phantom}.stl"}}]})
    assert [c.params["path"] for c in expand_grid(cfg)] == ["exports/seg.stl"]

def test_each_unreadable_path_names_its_own_cause(tmp_path):
    import os

    sphere = trimesh.creation.icosphere(subdivisions=2)
    v = np.array(sphere.vertices)
    v[0] = np.nan
    lines = [f"v {a} {b} {c}" for a, b, c in v] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in sphere.faces]
    (tmp_path / "nan.obj").write_text("\n".join(lines) + "\n")
    os.mkfifo(tmp_path / "pipe.stl")
    (tmp_path / "folder.stl").mkdir()
    vol = get_phantom("sphere").volume(n=16)
    for path, words in ((tmp_path / "nan.obj", "has 1 vertices with a NaN or infinite coordinate"),
                        (tmp_path / "pipe.stl", "is a FIFO, not a mesh file"),      # read, it would block
                        (tmp_path / "folder.stl", "is a folder, not a mesh file"),
                        ("/dev/zero", "is a device, not a mesh file")):             # read, it would never end
        with pytest.raises(InputError) as err:
            get_method("mesh_file", path=str(path)).reconstruct(vol)
        text = str(err.value)
        assert words in text and "\n" not in text and "no such mesh file" not in text, text
        assert "not a closed mesh" not in text, text


def test_check_method_says_in_one_line_that_its_cases_cannot_judge_an_importer(capsys):
    from bench.check import check_method
    from bench.cli import main

    assert main(["check-method", "mesh_file"]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert captured.out == "" and len(err) == 1 and "reads a surface made elsewhere" in err[0], captured
    assert "violation" not in captured.err
    with pytest.raises(InputError, match="check-method's cases cannot judge it"):
        check_method(get_method("mesh_file", path="x.stl"))
