"""The last input gaps (issue 30): timeouts beyond what the platform can wait for, a negative seed, a spacing
whose grid is not representable, control characters in user text — each one line on stderr, exit 2."""

from __future__ import annotations

import numpy as np
import pytest

from bench.cli import main
from bench.run.limits import MAX_SECONDS, TimeLimits
from bench.terminal import printable
from phantoms import InputError, Volume, get_phantom, load_volume

GRID = '[grid]\nphantoms = ["sphere"]\nn = [24]\n[[methods]]\nname = "marching_cubes"\n'


def _one_error_line(err: str, *needles: str) -> None:
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert "Traceback" not in err and all(n in err for n in needles), err


@pytest.mark.parametrize("option", ["--timeout", "--method-timeout", "--score-timeout"])
def test_a_timeout_beyond_the_platform_is_refused_before_the_run(option, tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["run", "--quick", option, "3e6", "--out", str(out)]) == 2   # 3e9 ms > 2**31 ms
    _one_error_line(capsys.readouterr().err, option, "2147483")
    assert not out.exists()      # no header-only results.csv


def test_a_config_timeout_beyond_the_platform_is_refused(tmp_path, capsys):
    cfg = tmp_path / "g.toml"
    cfg.write_text(GRID + "[run]\nmethod_timeout = 1e10\n")
    assert main(["run", "--config", str(cfg), "--out", str(tmp_path / "o")]) == 2
    _one_error_line(capsys.readouterr().err, "run.method_timeout")
    assert not (tmp_path / "o").exists()


def test_the_longest_timeout_accepted_runs(tmp_path, capsys):
    """The bound is what the executor can really wait for: a cell under the largest limit completes."""
    cfg = tmp_path / "g.toml"
    cfg.write_text(GRID)
    out = tmp_path / "o"
    limit = f"{MAX_SECONDS:.0f}"
    assert main(["run", "--config", str(cfg), "--out", str(out), "--jobs", "1", "--no-report", "--timeout", limit,
                 "--method-timeout", limit, "--score-timeout", limit]) == 0
    assert "1 ok" in capsys.readouterr().out
    with pytest.raises(InputError, match="score timeout"):
        TimeLimits(score=MAX_SECONDS * 2)


def test_volume_with_a_negative_seed_is_one_line(tmp_path, capsys):
    out = tmp_path / "v.npz"
    args = ["volume", "sphere", "--n", "16", "--noise", "gaussian", "--snr", "30", "--seed", "-1", "-o", str(out)]
    assert main(args) == 2
    _one_error_line(capsys.readouterr().err, "seed", "-1")
    assert not out.exists()


@pytest.mark.parametrize("spacing", [1e-300, 1e300, 1e-120, 1e120])
def test_a_spacing_whose_grid_is_not_a_normal_float_is_refused_on_loading(spacing, tmp_path, capsys):
    values = get_phantom("sphere").volume(n=24).values
    path = tmp_path / "tiny.npz"
    np.savez(path, values=values, origin=np.zeros(3), spacing=np.full(3, spacing))
    for cmd in (["info", str(path)], ["reconstruct", str(path), "-m", "marching_cubes", "-o", str(tmp_path / "m.ply")]):
        assert main(cmd) == 2
        err = capsys.readouterr().err
        _one_error_line(err, "spacing", "24×24×24", "rescale")
        assert "marching_cubes" not in err           # the method is not blamed
    with pytest.raises(InputError, match="spacing"):
        Volume(values, np.zeros(3), spacing)


@pytest.mark.parametrize("spacing", [0.5, 1e-3, 1e-9, [1e-3, 0.5, 2.0]])
def test_physical_spacings_are_kept_and_printed_with_their_digits(spacing, tmp_path, capsys):
    values = get_phantom("sphere").volume(n=24).values
    path = tmp_path / "v.npz"
    np.savez(path, values=values, origin=np.zeros(3), spacing=np.asarray(spacing, float))
    assert np.allclose(load_volume(path).spacing, spacing)
    assert main(["info", str(path)]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("spacing:"))
    assert "0.0," not in line and "0.0]" not in line   # 1e-9 m is not printed as 0.0
    assert str(np.atleast_1d(spacing)[0]) in line


def test_printable_escapes_terminal_controls_and_keeps_the_text():
    evil = "grid\x1b]0;pwned\x07 \x1b[2J\rname\x9b1m\u202e"
    shown = printable(evil)
    assert not any(c in shown for c in "\x1b\x07\r\x9b\u202e")
    assert shown == "grid\\x1b]0;pwned\\x07 \\x1b[2J\\x0dname\\x9b1m\\u202e"
    assert printable("a\tb\nc — é") == "a\tb\nc — é"


def test_a_config_name_with_escape_sequences_reaches_the_terminal_escaped(tmp_path, capsys):
    cfg = tmp_path / "g.toml"
    cfg.write_text('name = "evil\\u001b]0;title\\u0007\\u001b[2J"\n' + GRID)
    assert main(["run", "--config", str(cfg), "--out", str(tmp_path / "o"), "--dry-run"]) == 0
    cap = capsys.readouterr()
    assert "\x1b" not in cap.out + cap.err and "evil\\x1b]0;title\\x07" in cap.out


def test_an_error_message_with_escape_sequences_is_escaped(tmp_path, capsys):
    assert main(["run", "--quick", "--phantoms", "no\x1b[2Jsuch", "--out", str(tmp_path / "o"), "--dry-run"]) == 2
    err = capsys.readouterr().err
    assert "\x1b" not in err and "no\\x1b[2Jsuch" in err
