"""``python -m bench methods`` and ``python -m bench reconstruct`` through the CLI entry point."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh

from bench.cli import main
from phantoms import get_phantom, save_volume

BUILTINS = ["marching_cubes", "mc_taubin", "distmesh", "poisson"]


@pytest.fixture(scope="module")
def sphere_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("vol") / "sphere.npz"
    save_volume(path, get_phantom("sphere").volume(n=40))
    return path


def test_methods_lists_every_method_with_params_and_defaults(capsys):
    assert main(["methods"]) == 0
    out = capsys.readouterr().out
    for name in BUILTINS:
        assert f"\n{name} — " in "\n" + out
    # parameters with types, defaults and docs
    assert "step_size" in out and "default 1" in out
    assert "lorensen" in out
    assert "max_iter" in out and "default 2000" in out
    assert "h0" in out and "default auto" in out
    assert "depth" in out and "samples_per_node" in out
    assert "lamb" in out and "default 0.53" in out


def test_methods_single_and_unknown(capsys):
    assert main(["methods", "distmesh"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("distmesh") and "poisson" not in out.split("\n")[0]
    assert main(["methods", "nope"]) == 2
    err = capsys.readouterr().err
    assert "unknown method 'nope'" in err and "marching_cubes" in err


@pytest.mark.parametrize("suffix", [".ply", ".obj", ".stl"])
def test_reconstruct_writes_each_format(sphere_file, tmp_path, capsys, suffix):
    out = tmp_path / f"mesh{suffix}"
    assert main(["reconstruct", str(sphere_file), "--method", "marching_cubes", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    for key in ("vertices:", "faces:", "watertight:   yes", "euler:        2", "time:"):
        assert key in text, key
    mesh = trimesh.load(out, force="mesh")
    assert mesh.is_watertight and mesh.euler_number == 2 and mesh.volume > 0
    n_vertices = int(text.split("vertices:")[1].split()[0])
    assert len(mesh.vertices) == n_vertices


def test_reconstruct_with_params_and_info_json(sphere_file, tmp_path, capsys):
    out = tmp_path / "dm.ply"
    info = tmp_path / "info.json"
    rc = main(["reconstruct", str(sphere_file), "-m", "distmesh", "--set", "max_iter=30", "--set", "h0=0.25",
               "-o", str(out), "--info-json", str(info)])
    assert rc == 0
    text = capsys.readouterr().out
    assert "iterations:" in text and "stop_reason:" in text and "max_iter" in text
    data = json.loads(info.read_text())
    assert data["params"]["max_iter"] == 30 and data["params"]["h0"] == 0.25
    assert data["info"]["iterations"] == 30 and data["info"]["converged"] is False
    assert data["mesh"]["watertight"] is True and data["mesh"]["euler"] == 2
    assert trimesh.load(out, force="mesh").is_watertight


def test_reconstruct_taubin_and_poisson(sphere_file, tmp_path, capsys):
    for method, sets in (("mc_taubin", ["iterations=4"]), ("poisson", ["depth=6"])):
        out = tmp_path / f"{method}.obj"
        args = ["reconstruct", str(sphere_file), "-m", method, "-o", str(out)]
        for s in sets:
            args += ["--set", s]
        assert main(args) == 0, method
        mesh = trimesh.load(out, force="mesh")
        assert mesh.is_watertight and mesh.volume > 0
    capsys.readouterr()


@pytest.mark.parametrize("args, message", [
    (["-m", "nope"], "unknown method 'nope'; valid methods:"),
    (["-m", "distmesh", "--set", "max_iter=abc"], "method 'distmesh', parameter 'max_iter': expected int"),
    (["-m", "distmesh", "--set", "max_iter=0"], "method 'distmesh', parameter 'max_iter'"),
    (["-m", "marching_cubes", "--set", "method=cubes"], "method 'marching_cubes', parameter 'method'"),
    (["-m", "poisson", "--set", "bogus=1"], "method 'poisson' has no parameter 'bogus'"),
    (["-m", "poisson", "--set", "depth"], "--set expects key=value"),
    (["-m", "marching_cubes", "--set", "step_size=1", "--set", "step_size=2"], "twice"),
])
def test_reconstruct_bad_arguments_exit_2(sphere_file, tmp_path, capsys, args, message):
    rc = main(["reconstruct", str(sphere_file), *args, "-o", str(tmp_path / "x.ply")])
    assert rc == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and message in err and "Traceback" not in err
    assert not (tmp_path / "x.ply").exists()


def test_reconstruct_bad_files_exit_2(sphere_file, tmp_path, capsys):
    assert main(["reconstruct", str(sphere_file), "-m", "marching_cubes", "-o", str(tmp_path / "x.vtk")]) == 2
    assert "unknown mesh format '.vtk'" in capsys.readouterr().err
    assert main(["reconstruct", str(tmp_path / "missing.npz"), "-m", "marching_cubes",
                 "-o", str(tmp_path / "x.ply")]) == 2
    capsys.readouterr()
    # a volume with no zero crossing: the method names itself
    empty = tmp_path / "empty.npz"
    save_volume(empty, get_phantom("sphere").volume(n=16).with_values(np.full((16, 16, 16), 2.5)))
    assert main(["reconstruct", str(empty), "-m", "poisson", "-o", str(tmp_path / "x.ply")]) == 2
    err = capsys.readouterr().err
    assert "method 'poisson'" in err and "no zero crossing" in err


def test_reconstruct_reads_a_mask(tmp_path, capsys):
    vol = get_phantom("sphere").volume(n=32)
    mask_path = tmp_path / "mask.npy"
    np.save(mask_path, (vol.values < 0).astype(np.uint8))
    out = tmp_path / "mask.ply"
    assert main(["reconstruct", str(mask_path), "-m", "marching_cubes", "--mask", "-o", str(out)]) == 0
    assert "watertight:   yes" in capsys.readouterr().out


# ------------------------------------------------------------------ output paths checked before the method runs
@pytest.fixture
def counted_runs(monkeypatch):
    """Counts reconstructions of marching_cubes (to show an output path is checked before the method runs)."""
    from methods.marching_cubes import MarchingCubes

    calls = []
    real = MarchingCubes.reconstruct
    monkeypatch.setattr(MarchingCubes, "reconstruct", lambda self, v: calls.append(1) or real(self, v))
    return calls


@pytest.mark.parametrize("which", ["-o", "--info-json"])
def test_reconstruct_output_paths_are_checked_before_the_method_runs(sphere_file, tmp_path, capsys, counted_runs,
                                                                      which):
    blocked = tmp_path / ("m.ply" if which == "-o" else "i.json")
    blocked.mkdir()                                            # a directory in the way
    args = ["-o", str(tmp_path / "m.ply"), "--info-json", str(tmp_path / "i.json")]
    assert main(["reconstruct", str(sphere_file), "-m", "marching_cubes", *args]) == 2
    assert capsys.readouterr().err.strip() == f"error: cannot write '{blocked}': it is a directory"
    assert counted_runs == []                                  # the method never ran


def test_reconstruct_disk_full_is_one_line_and_leaves_no_temp_file(sphere_file, tmp_path, capsys, monkeypatch):
    from _fs import small_tmpfs

    with small_tmpfs(tmp_path / "disk", size="16k") as disk:
        if disk is None:  # not root: simulate ENOSPC for the mesh write
            import errno

            import trimesh

            disk = tmp_path / "disk"

            def full(self, file_obj=None, **kw):
                open(file_obj, "wb").close()
                raise OSError(errno.ENOSPC, "No space left on device")

            monkeypatch.setattr(trimesh.Trimesh, "export", full)
        assert main(["reconstruct", str(sphere_file), "-m", "marching_cubes", "-o", str(disk / "m.ply")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert err == [f"error: cannot write '{disk / 'm.ply'}': No space left on device"]
        assert sorted(p.name for p in disk.iterdir()) == []    # neither the mesh nor a temp file


def test_reconstruct_refuses_a_diverged_mesh_instead_of_writing_inf(sphere_file, tmp_path, capsys):
    """mc_taubin with λ = μ = 1 for 3000 passes blows the sphere up to ~1e97: beyond float32, so a PLY would
    hold only inf (main wrote it, 'watertight: yes').  It is a failed reconstruction: exit 1, nothing written."""
    out = tmp_path / "m.ply"
    with np.errstate(all="ignore"):
        rc = main(["reconstruct", str(sphere_file), "-m", "mc_taubin", "--set", "lamb=1", "--set", "mu=1",
                   "--set", "iterations=3000", "-o", str(out)])
    assert rc == 1
    err = capsys.readouterr().err
    assert "returned non-finite vertex coordinates" in err and "nothing written" in err
    assert not out.exists()


def test_reconstruct_with_a_failing_plugin_is_one_line_and_writes_nothing(sphere_file, tmp_path, capsys,
                                                                        monkeypatch):
    from methods.marching_cubes import MarchingCubes

    def bug(self, volume):
        raise ValueError("index 7 is out of bounds\nfor axis 0 with size 3")

    monkeypatch.setattr(MarchingCubes, "reconstruct", bug)
    out = tmp_path / "x.ply"
    rc = main(["reconstruct", str(sphere_file), "-m", "marching_cubes", "-o", str(out)])
    err = capsys.readouterr().err
    assert err.strip() == ("error: method 'marching_cubes' failed: ValueError: index 7 is out of bounds for axis 0 "
                           "with size 3") and rc == 1
    assert not out.exists()


def test_reconstruct_with_faces_naming_missing_vertices_writes_nothing(sphere_file, tmp_path, capsys, monkeypatch):
    from methods import Reconstruction
    from methods.marching_cubes import MarchingCubes

    def bad_faces(self, volume):
        mesh = trimesh.Trimesh(np.eye(3), np.array([[0, 1, 2], [0, 1, 7]]), process=False)
        return Reconstruction(mesh, {})

    monkeypatch.setattr(MarchingCubes, "reconstruct", bad_faces)
    out = tmp_path / "x.ply"
    rc = main(["reconstruct", str(sphere_file), "-m", "marching_cubes", "-o", str(out)])
    err = capsys.readouterr().err
    assert rc == 1 and "bad indices" in err and "nothing written" in err and "Traceback" not in err, err
    assert not out.exists()


def test_reconstruct_with_a_plugin_out_of_memory_is_one_line(sphere_file, tmp_path, capsys, monkeypatch):
    from methods.marching_cubes import MarchingCubes

    def boom(self, volume):
        raise MemoryError()

    monkeypatch.setattr(MarchingCubes, "reconstruct", boom)
    rc = main(["reconstruct", str(sphere_file), "-m", "marching_cubes", "-o", str(tmp_path / "x.ply")])
    err = capsys.readouterr().err
    assert rc == 1 and err.strip() == "error: method 'marching_cubes' ran out of memory"


@pytest.mark.parametrize("how, words", [("signal", "ended its process (signal SIGKILL"),
                                        ("exit", "ended its process (exit code 3")])
def test_reconstruct_with_a_plugin_that_kills_its_process_is_one_line(sphere_file, tmp_path, capsys, monkeypatch,
                                                                        how, words):
    import os
    import signal

    from methods.marching_cubes import MarchingCubes

    def crash(self, volume):
        if how == "signal":
            os.kill(os.getpid(), signal.SIGKILL)      # as a segfault in compiled code would end it
        os._exit(3)

    monkeypatch.setattr(MarchingCubes, "reconstruct", crash)
    out = tmp_path / "x.ply"
    rc = main(["reconstruct", str(sphere_file), "-m", "marching_cubes", "-o", str(out)])
    err = capsys.readouterr().err
    assert rc == 1 and err.startswith(f"error: method 'marching_cubes' {words}") and err.count("\n") == 1, err
    assert not out.exists()


def test_reconstruct_of_an_input_the_method_declines_is_one_line_exit_2(sphere_file, tmp_path, capsys):
    import hook_plugins  # noqa: F401  (registers picky_mc)

    out = tmp_path / "m.ply"
    args = ["reconstruct", str(sphere_file), "-m", "picky_mc", "--set", "min_n=41", "-o", str(out)]
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["error: method 'picky_mc' skips this input: the grid has 40 points per axis, fewer than the "
                   "41 it needs"] and not out.exists()


def test_reconstruct_times_the_method_after_its_warm_up(sphere_file, tmp_path, capsys, monkeypatch):
    import hook_plugins

    monkeypatch.setattr(hook_plugins, "_WARMED", [])
    info = tmp_path / "info.json"
    assert main(["reconstruct", str(sphere_file), "-m", "warm_mc", "-o", str(tmp_path / "m.ply"),
                 "--info-json", str(info)]) == 0
    assert json.loads(info.read_text())["wall_s"] < hook_plugins.WARM_SECONDS


def test_reconstruct_with_a_plugin_raising_keyboard_interrupt_is_its_failure_not_a_ctrl_c(sphere_file, tmp_path,
                                                                                          capsys, monkeypatch):
    """The method's KeyboardInterrupt comes from its child process: it is the method's failure (exit 1), not the
    user's interruption (130, 'interrupted')."""
    from methods.marching_cubes import MarchingCubes

    def interrupts(self, volume):
        raise KeyboardInterrupt

    monkeypatch.setattr(MarchingCubes, "reconstruct", interrupts)
    rc = main(["reconstruct", str(sphere_file), "-m", "marching_cubes", "-o", str(tmp_path / "x.ply")])
    err = capsys.readouterr().err
    assert rc == 1 and err.startswith("error: method 'marching_cubes' raised KeyboardInterrupt") and \
        err.count("\n") == 1, err


def test_reconstruct_with_a_200000_character_message_shows_2000_and_the_length(sphere_file, tmp_path, capsys,
                                                                                monkeypatch):
    from methods.marching_cubes import MarchingCubes

    def floods(self, volume):
        raise RuntimeError("x" * 200_000)

    monkeypatch.setattr(MarchingCubes, "reconstruct", floods)
    rc = main(["reconstruct", str(sphere_file), "-m", "marching_cubes", "-o", str(tmp_path / "x.ply")])
    err = capsys.readouterr().err
    assert rc == 1 and err.count("\n") == 1 and len(err) < 2200 and err.rstrip().endswith("… (200,046 characters)"), \
        err[-100:]


def test_reconstruct_names_every_spacing_and_a_mesh_file_in_lps_gets_the_truths_hint(tmp_path, capsys):
    """An anisotropic grid prints its three spacings; an LPS export read by mesh_file says "negate x and y"."""
    from _volumes import write_boxes

    nii, obj = write_boxes(tmp_path)
    assert main(["reconstruct", str(nii), "-m", "marching_cubes", "-o", str(tmp_path / "mc.ply")]) == 0
    assert "spacing 0.5 × 0.5 × 0.8)" in capsys.readouterr().out
    mesh = trimesh.load(str(obj), process=False)
    trimesh.Trimesh(mesh.vertices * [-1, -1, 1], mesh.faces[:, ::-1], process=False).export(str(tmp_path / "lps.obj"))
    assert main(["reconstruct", str(nii), "-m", "mesh_file", "--set", f"path={obj}", "-o",
                 str(tmp_path / "ok.ply")]) == 0
    capsys.readouterr()
    assert main(["reconstruct", str(nii), "-m", "mesh_file", "--set", f"path={tmp_path / 'lps.obj'}", "-o",
                 str(tmp_path / "lps.ply")]) == 2
    err = capsys.readouterr().err
    assert "not in the volume's world coordinates (RAS+); it fits the volume in LPS coordinates (negate x and y" in err


def test_reconstruct_says_a_long_method_is_still_running(sphere_file, tmp_path, capsys, monkeypatch):
    import bench.cli.methods as cli_methods

    monkeypatch.setattr(cli_methods, "TICK_FIRST_S", 0.3)
    monkeypatch.setattr(cli_methods, "TICK_EVERY_S", 0.3)
    assert main(["reconstruct", str(sphere_file), "-m", "sleepy_mc", "--set", "seconds=1.2", "--import",
                 "hook_plugins", "-o", str(tmp_path / "m.ply")]) == 0
    ticks = [ln for ln in capsys.readouterr().err.splitlines() if "still running" in ln]
    assert len(ticks) >= 2 and ticks[0].startswith("reconstruct: method 'sleepy_mc' still running (")
    monkeypatch.setattr(cli_methods, "TICK_FIRST_S", 5.0)
    assert main(["reconstruct", str(sphere_file), "-m", "marching_cubes", "-o", str(tmp_path / "q.ply")]) == 0
    assert "still running" not in capsys.readouterr().err          # a quick method: no ticks


def test_reconstruct_names_a_zero_area_mesh_invalid(sphere_file, tmp_path, capsys):
    assert main(["reconstruct", str(sphere_file), "-m", "degenerate_mesh", "--import", "hook_plugins", "-o",
                 str(tmp_path / "d.ply")]) == 1
    assert "empty mesh: zero area" in capsys.readouterr().err
