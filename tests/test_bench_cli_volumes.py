"""The foundation's command line: phantoms, volume, info; --help everywhere; bad input → exit 2."""

import subprocess
import sys

import numpy as np
import pytest

from bench.cli import build_parser, main
from phantoms import load_volume


def run(*args):
    return subprocess.run([sys.executable, "-m", "bench", *args], capture_output=True, text=True, timeout=120)


def test_help_on_every_subcommand(capsys):
    """Every subcommand's --help in this process (argparse exits 0), and once through ``python -m bench``."""
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    for name in sub.choices:
        with pytest.raises(SystemExit) as exc:
            main([name, "--help"])
        assert exc.value.code in (0, None), name
        assert "usage:" in capsys.readouterr().out, name
    r = run("run", "--help")
    assert r.returncode == 0 and "usage:" in r.stdout, r.stderr


@pytest.mark.parametrize("args, says", [
    (["run", "--quick", "--dry-run", "--memory-limit", "-1"], "argument --memory-limit: must be a finite number >= 0"),
    (["run", "--quick", "--dry-run", "--timeout", "-5"], "argument --timeout: must be a finite number >= 0: '-5'"),
    (["volume", "sphere", "-o", "x.npz", "--snr", "nan"], "argument --snr: must be finite: 'nan'"),
    (["table", "--format", "xml", "somewhere"], "argument --format: invalid choice: 'xml'"),
    (["run", "--config", "g.toml", "--quick"], "argument --quick: not allowed with argument --config"),
    (["info"], "the following arguments are required: file"),
    (["nosuch"], "argument COMMAND: invalid choice: 'nosuch'"),
    (["run", "--quick", "--bogus\n\x1b[2J"], "unrecognized arguments: --bogus\\n\\x1b[2J"),
])
def test_an_argparse_error_is_one_line_and_exit_2(args, says, capsys):
    """argparse's own errors as every other error: one line (no usage block), control characters and newlines of
    the command line shown escaped, exit 2 — and where the usage is."""
    with pytest.raises(SystemExit) as exc:
        main(args)
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert exc.value.code == 2 and captured.out == "" and len(lines) == 1, captured.err
    assert lines[0].startswith("error: ") and says in lines[0] and "usage: python -m bench" in lines[0], lines[0]
    assert "\x1b" not in captured.err


def test_an_argparse_error_through_python_m_bench():
    r = run("run", "--timeout", "-5")
    assert r.returncode == 2 and r.stdout == "", r
    assert r.stderr == ("error: argument --timeout: must be a finite number >= 0: '-5' "
                        "(usage: python -m bench run --help)\n")


def test_phantoms_lists_every_phantom(capsys):
    assert main(["phantoms"]) == 0
    out = capsys.readouterr().out
    for name in ("sphere", "ellipsoid", "fused_spheres", "cylinder", "torus", "vault_shell", "lattice"):
        assert name in out
    assert "high genus; options: n=&extent=&seed=&cells=&strut=" in out
    assert "44.5 dB" in out and "radius=0.4" in out


def test_volume_writes_npz_and_reports_snr(tmp_path):
    out = tmp_path / "e.npz"
    r = run("volume", "ellipsoid", "--n", "24", "--noise", "gaussian", "--snr", "30", "--seed", "2", "-o", str(out))
    assert r.returncode == 0, r.stderr
    assert "achieved" in r.stdout
    achieved = float(r.stdout.split("achieved")[1].split("dB")[0])
    assert abs(achieved - 30) < 0.2
    vol = load_volume(out)
    assert vol.shape == (24, 24, 24) and np.isclose(vol.h, 5 / 23)
    with np.load(out) as data:
        assert set(data.files) == {"values", "origin", "spacing"}


def test_info(tmp_path, capsys):
    out = tmp_path / "s.npz"
    assert main(["volume", "sphere", "--n", "16", "-o", str(out)]) == 0
    capsys.readouterr()
    assert main(["info", str(out)]) == 0
    text = capsys.readouterr().out
    assert "(16, 16, 16)" in text and "closed:       yes" in text
    big = tmp_path / "big.npz"
    # a sphere of radius 3 in [-2.5, 2.5]³ is cut by the grid boundary
    xyz = np.stack(np.meshgrid(*[np.linspace(-2.5, 2.5, 16)] * 3, indexing="ij"))
    np.savez(big, values=np.linalg.norm(xyz, axis=0) - 3)
    assert main(["info", str(big)]) == 0
    assert "closed:       no" in capsys.readouterr().out


@pytest.mark.parametrize(
    "args, message",
    [
        (["volume", "blob", "-o", "x.npz"], "valid phantoms"),
        (["volume", "sphere", "--n", "4", "-o", "x.npz"], "N must be an integer >= 8"),
        (["volume", "sphere", "--noise", "gaussian", "--snr", "nan", "-o", "x.npz"], "must be finite"),
        (["info", "does-not-exist.npz"], "no such file"),
    ],
)
def test_bad_input_exit_code_2(tmp_path, args, message):
    r = subprocess.run([sys.executable, "-m", "bench", *args], capture_output=True, text=True, cwd=tmp_path,
                       timeout=120)
    assert r.returncode == 2
    assert message in r.stderr
    assert "Traceback" not in r.stderr


@pytest.mark.heavy   # end-to-end, > 10 s: run by .ci/run's `pytest -m heavy`
def test_info_bad_files_exit_2(tmp_path):
    (tmp_path / "t.npz").write_bytes(b"PK\x03\x04 truncated")
    np.save(tmp_path / "nan.npy", np.full((8, 8, 8), np.nan))
    np.save(tmp_path / "flat.npy", np.zeros((8, 8)))
    np.save(tmp_path / "empty.npy", np.zeros((8, 8, 8), bool))
    for name, msg in [("t.npz", "cannot read"), ("nan.npy", "NaN"), ("flat.npy", "3-D"),
                      ("empty.npy", "no inside voxels")]:
        r = run("info", str(tmp_path / name))
        assert r.returncode == 2, name
        assert msg in r.stderr and "Traceback" not in r.stderr


# ---------------------------------------------------------------------------------------------- issue 16
def test_volume_too_large_for_memory_is_one_line_with_the_largest_n(tmp_path, capsys):
    assert main(["volume", "sphere", "--n", "3000", "-o", str(tmp_path / "big.npz")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "N = 3000 volume" in err[0] and "the largest N³ grid that fits is N = " in err[0]
    assert not (tmp_path / "big.npz").exists()


def test_volume_output_is_checked_before_the_volume_is_computed(tmp_path, capsys, monkeypatch):
    import phantoms.base as base

    computed = []
    real = base.grid_volume
    monkeypatch.setattr(base, "grid_volume", lambda *a, **k: computed.append(1) or real(*a, **k))
    (tmp_path / "dir.npz").mkdir()
    assert main(["volume", "sphere", "--n", "16", "-o", str(tmp_path / "dir.npz")]) == 2
    assert capsys.readouterr().err.strip() == f"error: cannot write '{tmp_path / 'dir.npz'}': it is a directory"
    assert computed == []
    assert main(["volume", "sphere", "--n", "16", "-o", str(tmp_path / "ok.npz")]) == 0 and computed == [1]


def test_volume_on_a_read_only_file_system_is_one_line(tmp_path, capsys, monkeypatch):
    from _fs import small_tmpfs

    with small_tmpfs(tmp_path / "ro", read_only=True) as ro:
        if ro is None:  # not root: simulate EROFS at the probe write
            import errno
            import pathlib

            def erofs(self, data):
                raise OSError(errno.EROFS, "Read-only file system")

            ro = tmp_path / "ro"
            monkeypatch.setattr(pathlib.Path, "write_bytes", erofs)
        assert main(["volume", "sphere", "--n", "16", "-o", str(ro / "v.npz")]) == 2
    assert capsys.readouterr().err.strip() == f"error: cannot write '{ro / 'v.npz'}': Read-only file system"


def test_info_into_a_closed_pipe_exits_quietly(tmp_path):
    """``info f | head``: the reader went away before the output: no BrokenPipeError traceback."""
    import os

    from phantoms import get_phantom, save_volume

    path = save_volume(tmp_path / "v.npz", get_phantom("sphere").volume(n=16))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    proc = subprocess.Popen([sys.executable, "-m", "bench", "info", str(path)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, env=env)
    proc.stdout.close()                                       # the reader is gone before anything is written
    err = proc.stderr.read().decode()
    proc.wait(timeout=120)
    assert "Traceback" not in err and "BrokenPipeError" not in err, err
    assert proc.returncode == 141


def test_info_honours_labels_and_label(tmp_path, capsys):
    """labels=all / labels=1,3: one described phantom per label; an absent label: exit 2 naming those present."""
    import nibabel as nib

    lab = np.zeros((20, 20, 20), np.uint8)
    lab[3:9, 3:9, 3:9] = 1
    lab[11:17, 11:17, 11:17] = 3
    nib.save(nib.Nifti1Image(lab, np.eye(4)), str(tmp_path / "seg.nii.gz"))
    seg = tmp_path / "seg.nii.gz"
    for opts in ("labels=all", "labels=1,3"):
        assert main(["info", f"volume:{seg}?{opts}"]) == 0
        out = capsys.readouterr().out
        assert "2 phantom(s): seg_label1, seg_label3" in out and "no zero level set" not in out
        assert out.count("closed:       yes") == 2
    assert main(["info", f"volume:{seg}?label=3"]) == 0 and "closed:       yes" in capsys.readouterr().out
    for opts in ("labels=1,4", "label=4"):
        assert main(["info", f"volume:{seg}?{opts}"]) == 2
        assert "label 4 does not occur in the image; labels present: " in capsys.readouterr().err
