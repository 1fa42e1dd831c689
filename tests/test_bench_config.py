"""bench.config: the TOML schema, validated before any work; command-line method and noise specs."""

from __future__ import annotations

import pytest

from bench.config import builtin_config, config_from_dict, parse_noise_spec
from bench.specs import parse_method_spec
from phantoms import InputError


def test_method_and_noise_specs():
    m = parse_method_spec("sg0=shape_gradient:beta=0,snapshots=[1,50],preset=paper")
    assert (m.label, m.name, m.params) == ("sg0", "shape_gradient",
                                           {"beta": 0, "snapshots": [1, 50], "preset": "paper"})
    assert parse_method_spec("marching_cubes:step_size=2").label == "marching_cubes[step_size=2]"
    specs = parse_noise_spec("none,gaussian,uniform@40")
    assert [(s.kind, s.snr) for s in specs] == [("none", None), ("gaussian", "paper"), ("uniform", 40.0)]


def test_report_section_round_trips_and_is_checked_against_the_labels():
    cfg = builtin_config("paper")
    cols = cfg.report["paper_columns"]
    assert [c["label"] for c in cols] == ["shape_gradient[paper,beta=0]", "shape_gradient[paper]",
                                          "shape_gradient[paper]", "shape_gradient[paper+fixes,beta=0]",
                                          "shape_gradient[paper+fixes]", "shape_gradient[paper+fixes]"]
    assert [c["noise"] for c in cols] == ["none", "none", "gaussian"] * 2
    assert cfg.report["uniform_label"] == ["shape_gradient[paper]", "shape_gradient[paper+fixes]"]
    assert config_from_dict(cfg.to_dict()).report == cfg.report
    cfg.validate()
    data = cfg.to_dict()
    data["report"]["paper_columns"][0]["label"] = "no_such_label"
    with pytest.raises(InputError, match=r"report.paper_columns\[0\]: label 'no_such_label'"):
        config_from_dict(data).validate()
    data = cfg.to_dict()
    data["report"]["paper_columns"][0]["noise"] = "pink"
    with pytest.raises(InputError, match="unknown noise kind 'pink'"):
        config_from_dict(data)
    data = cfg.to_dict()
    data["report"]["colour"] = "red"
    with pytest.raises(InputError, match="unknown key 'colour'"):
        config_from_dict(data)


def test_a_config_without_report_section_has_none():
    cfg = builtin_config("quick")
    assert cfg.report == {} and "report" not in cfg.to_dict()


def test_a_plugin_module_that_fails_to_import_is_one_input_error():
    cfg = builtin_config("quick")
    cfg.imports = ["no_such_module_for_levelset_bench"]
    with pytest.raises(InputError, match="run.imports: cannot import module 'no_such_module_for_levelset_bench'"):
        cfg.validate()


def test_a_key_in_both_params_and_sweep_is_refused(tmp_path, capsys):
    from bench.cli import main

    toml = ('[grid]\nphantoms = ["sphere"]\n[[methods]]\nname = "shape_gradient"\n'
            'params = { alpha = 5.0, beta = 1.0 }\nsweep = { beta = [0.0, 1.0] }\n')
    path = tmp_path / "both.toml"
    path.write_text(toml)
    assert main(["run", "--config", str(path), "--dry-run"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == ("error: methods[0]: parameter 'beta' is set in both params and sweep; keep it in one (the sweep "
                   "would silently replace the params value)")
    path.write_text(toml.replace("alpha = 5.0, beta = 1.0", "alpha = 5.0"))   # the same without the clash runs
    assert main(["run", "--config", str(path), "--dry-run"]) == 0
    assert "2 cells" in capsys.readouterr().out


def test_the_paper_grid_labels_name_every_variant_and_its_non_default_settings():
    """No row runs non-default parameters under a default-looking label: the plain `shape_gradient` row is the
    suite's default, the paper rows name their preset (and β = 0), and the β = 0 ablations run on clean volumes
    only, as in the paper's tables."""
    from bench.run import expand_grid

    cells = expand_grid(builtin_config("paper"))
    by_label: dict = {}
    for c in cells:
        by_label.setdefault(c.label, []).append(c)
    assert {c.params.get("preset") for c in by_label["shape_gradient[paper]"]} == {"paper"}
    assert {c.params.get("preset") for c in by_label["shape_gradient[paper+fixes]"]} == {"paper+fixes"}
    assert all(c.params == {} for c in by_label["shape_gradient"])
    for label in ("shape_gradient[paper,beta=0]", "shape_gradient[paper+fixes,beta=0]"):
        assert {c.noise for c in by_label[label]} == {"none"} and all(c.params["beta"] == 0 for c in by_label[label])
    fused = [c for c in by_label["shape_gradient[paper]"] if c.phantom == "fused_spheres"]
    assert all(c.params["max_iter"] == 150 and c.params["snapshots"] == [1, 75, 150] for c in fused)
    slow = {"reach_for_the_spheres", "flying_edges", "dual_contouring", "reach_for_the_arcs"}
    assert not slow & {c.method for c in cells}
    quick = expand_grid(builtin_config("quick"))
    assert all(c.params == {} for c in quick if c.label == "shape_gradient")


def test_a_method_can_be_limited_to_some_noise_kinds():
    data = {"name": "t", "grid": {"phantoms": ["sphere"], "n": 24, "noise": [{"kind": "none"}, {"kind": "gaussian",
                                                                                          "snr": 30}]},
            "methods": [{"name": "marching_cubes", "noise": ["gaussian"]}, {"name": "mc_taubin"}]}
    from bench.run import expand_grid

    cfg = config_from_dict(data)
    cfg.validate()
    got = [(c.method, c.noise) for c in expand_grid(cfg)]
    assert got == [("mc_taubin", "none"), ("marching_cubes", "gaussian"), ("mc_taubin", "gaussian")]
    assert config_from_dict(cfg.to_dict()).methods[0].noise == ("gaussian",)
    data["methods"][0]["noise"] = ["pink"]
    with pytest.raises(InputError, match=r"noise: expected a list of noise kinds"):
        config_from_dict(data)


@pytest.mark.parametrize("grid, metrics", [({"n": [float("inf")]}, {}), ({"seeds": [1e400]}, {}),
                                           ({"n": [float("nan")]}, {}), ({}, {"n_samples": float("nan")}),
                                           ({}, {"n_samples": float("inf")})])
def test_non_finite_numbers_where_an_integer_is_expected_are_one_line(grid, metrics):
    from phantoms import InputError

    with pytest.raises(InputError, match="expected an integer, got (inf|nan)"):
        config_from_dict({"grid": {"phantoms": ["sphere"], **grid}, "metrics": metrics})


def test_a_config_that_cannot_end_or_nests_too_deeply_is_one_line(tmp_path):
    import os

    from bench.config import load_config
    from phantoms import InputError

    deep = tmp_path / "deep.toml"
    deep.write_text("x = " + "[" * 4000 + "]" * 4000 + "\n")
    with pytest.raises(InputError, match="nests tables or arrays too deeply"):
        load_config(deep)
    with pytest.raises(InputError, match="not a regular file"):
        load_config("/dev/zero")
    fifo = tmp_path / "fifo.toml"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match="not a regular file"):
        load_config(fifo)


def test_a_grid_too_large_to_run_is_refused_before_it_is_expanded():
    import time

    from phantoms import InputError

    cfg = config_from_dict({"grid": {"phantoms": ["sphere"], "seeds": list(range(1000))},
                            "methods": [{"name": "marching_cubes", "sweep": {"step_size": list(range(1, 1001))}}]})
    t0 = time.perf_counter()
    with pytest.raises(InputError, match=r"up to 1e\+06 cells; at most 100,000"):
        cfg.validate()
    assert time.perf_counter() - t0 < 5


def test_a_method_parameter_given_twice_is_refused():
    from bench.specs import parse_method_spec
    from phantoms import InputError

    with pytest.raises(InputError, match="parameter 'k' is given twice"):
        parse_method_spec("mc=marching_cubes:k=5,k=6")


def test_a_missing_truth_file_is_refused_before_any_cell(tmp_path):
    import numpy as np

    from phantoms import InputError

    seg = tmp_path / "seg.npy"
    m = np.zeros((12, 12, 12), np.uint8)
    m[3:9, 3:9, 3:9] = 1
    np.save(seg, m)
    cfg = config_from_dict({"grid": {"phantoms": [f"volume:{seg}?truth={tmp_path / 'ref.obj'}"]},
                            "methods": [{"name": "marching_cubes"}]})
    with pytest.raises(InputError, match="no such truth file"):
        cfg.validate()


def test_a_truth_in_another_frame_is_refused_at_validation_before_any_cell(tmp_path):
    """A truth in voxel-index coordinates used to pass validation and fail every cell one by one; it is one
    InputError naming the frame before anything runs.  A volume that cannot be read is still left to its cells."""
    import numpy as np
    import trimesh

    from _volumes import BOX_ORIGIN, BOX_SPACING, write_boxes

    nii, obj = write_boxes(tmp_path)
    mesh = trimesh.load(str(obj), process=False)
    trimesh.Trimesh((mesh.vertices - np.asarray(BOX_ORIGIN)) / np.asarray(BOX_SPACING), mesh.faces,
                    process=False).export(str(tmp_path / "index.obj"))
    (tmp_path / "broken.nii.gz").write_bytes(b"not an image")

    def grid(volume, truth):
        return config_from_dict({"grid": {"phantoms": [{"volume": str(volume), "truth": str(truth)}], "n": [16],
                                          "noise": [{"kind": "none"}]}, "methods": [{"name": "marching_cubes"}]})

    grid(nii, obj).validate()
    with pytest.raises(InputError, match="the truth surface index.obj .*fits the volume in voxel-index coordinates"):
        grid(nii, tmp_path / "index.obj").validate()
    grid(tmp_path / "broken.nii.gz", obj).validate()          # unreadable volume: a failed row of its cells
