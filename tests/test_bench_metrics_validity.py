"""bench.metrics.validity: every class of invalid output is caught, with its reason; valid outputs pass."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from bench.metrics.validity import check_mesh
from phantoms import get_phantom


@pytest.fixture(scope="module")
def sphere_volume():
    return get_phantom("sphere").volume(n=40)


@pytest.fixture(scope="module")
def good():
    return trimesh.creation.icosphere(subdivisions=3, radius=1.0)


def _mesh(v, f):
    return trimesh.Trimesh(np.asarray(v, float), np.asarray(f), process=False)


def test_a_correct_mesh_is_valid(good, sphere_volume):
    assert check_mesh(good, sphere_volume) == []


def _nan(m):
    v = m.vertices.copy()
    v[3] = np.nan
    return _mesh(v, m.faces)


def _inward(m):
    return _mesh(m.vertices, m.faces[:, ::-1])


def _mixed(m):
    f = m.faces.copy()
    f[: len(f) // 2] = f[: len(f) // 2, ::-1]
    return _mesh(m.vertices, f)


def _index_coordinates(m, vol):
    return _mesh(vol.world_to_index(m.vertices), m.faces)


def _outside(m):
    return _mesh(m.vertices + [4.0, 0, 0], m.faces)


def _non_manifold(m):
    # a third face on one edge of the closed sphere (a fin)
    a, b = m.faces[0][:2]
    v = np.vstack([m.vertices, [[0.0, 0.0, 1.3]]])
    return _mesh(v, np.vstack([m.faces, [[a, b, len(v) - 1]]]))


@pytest.mark.parametrize("make, reason", [
    (lambda m, vol: _mesh(np.zeros((0, 3)), np.zeros((0, 3), int)), "empty"),
    (lambda m, vol: _nan(m), "non-finite"),
    (lambda m, vol: _mesh(m.vertices, m.faces[5:]), "open"),
    (lambda m, vol: _inward(m), "inward"),
    (lambda m, vol: _mixed(m), "inconsistently oriented"),
    (lambda m, vol: _index_coordinates(m, vol), "outside the volume"),
    (lambda m, vol: _outside(m), "outside the volume"),
    (lambda m, vol: _non_manifold(m), "non-manifold"),
    (lambda m, vol: _mesh(m.vertices * 0.5, m.faces), "off the zero set"),
])
def test_each_invalid_class_is_caught_with_its_reason(good, sphere_volume, make, reason):
    reasons = check_mesh(make(good, sphere_volume), sphere_volume)
    assert reasons and any(r.startswith(reason) for r in reasons), reasons


def test_a_mesh_slightly_off_the_box_or_the_level_set_is_still_valid(good, sphere_volume):
    h = sphere_volume.h
    assert check_mesh(_mesh(good.vertices * (1 + 0.3 * h), good.faces), sphere_volume) == []


@pytest.mark.heavy   # end-to-end, > 10 s: run by .ci/run's `pytest -m heavy`
def test_an_invalid_output_is_an_invalid_row_never_best_and_reconstruct_says_so(tmp_path):
    """Through the real command line: a plug-in whose mesh faces inward (it scores exactly like marching cubes on
    distances) is an `invalid` row with the reason, is never marked best, and `reconstruct` exits 1."""
    import csv
    import os
    import subprocess
    import sys
    from pathlib import Path

    from phantoms import save_volume

    tests = Path(__file__).resolve().parent
    env = dict(os.environ,
               PYTHONPATH=os.pathsep.join([str(tests), str(tests.parent), os.environ.get("PYTHONPATH", "")]))
    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "bench", "run", "--quick", "--phantoms", "sphere", "--noise", "none",
           "--method", "marching_cubes", "--add-method", "inward", "--import", "runner_plugins", "--out", str(out),
           "--jobs", "1"]
    proc = subprocess.run(cmd, cwd=tests.parent, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "1 invalid" in proc.stdout
    rows = {r["label"]: r for r in csv.DictReader(open(out / "results.csv"))}
    assert rows["marching_cubes"]["status"] == "ok"
    assert rows["inward"]["status"] == "invalid" and rows["inward"]["error"].startswith("invalid: inward")
    # the metrics are kept — and an inward mesh scores like the correct one (only the samples' order differs)
    assert float(rows["inward"]["hausdorff"]) == pytest.approx(float(rows["marching_cubes"]["hausdorff"]), rel=0.01)
    page = (out / "index.html").read_text()
    table = page[page.index("sphere — signed distance, clean"):]
    table = table[:table.index("</table>")]
    rows_html = {}
    for chunk in table.split("<tr>")[1:]:
        cells = chunk.split("</tr>")[0]
        rows_html[cells.split("<td>", 1)[-1].split("</td>", 1)[0]] = cells
    # with one valid method nothing is "best" (one value); the invalid one is never marked
    assert 'class="best"' not in rows_html["inward"], rows_html["inward"]
    assert table.index("<td>marching_cubes</td>") < table.index("<td>inward</td>")   # validity first
    vol = save_volume(tmp_path / "s.npz", get_phantom("sphere").volume(n=32))
    script = ("import sys, runner_plugins; from bench.cli import main; "     # reconstruct has no --import yet
              f"sys.exit(main(['reconstruct', {str(vol)!r}, '--method', 'inward', '-o', {str(tmp_path / 'm.ply')!r}]))")
    rec = subprocess.run([sys.executable, "-c", script], cwd=tests.parent, env=env, capture_output=True, text=True,
                         timeout=300)
    assert rec.returncode == 1 and "invalid mesh" in rec.stderr and "inward" in rec.stderr


#: broken kind (tests/runner_plugins.py) -> the reason check_mesh must give
_BROKEN_REASONS = {"nonfinite": "non-finite", "empty": "empty", "open": "open", "inward": "inward",
                   "mixed": "inconsistently oriented", "index": "outside the volume", "outside": "outside the volume",
                   "nonmanifold": "non-manifold"}


@pytest.mark.heavy
def test_every_invalid_class_is_invalid_in_the_grid_never_best_and_in_reconstruct(tmp_path, monkeypatch, capsys):
    """One grid run with a correct method and one broken plug-in per invalid class: each broken one is an
    `invalid` row with its reason and is never marked best (its distances are often the best of the table);
    `reconstruct` with each exits 1 and names the reason."""
    import csv
    import os
    import subprocess
    import sys
    from pathlib import Path

    from bench.cli import main
    from phantoms import save_volume

    tests = Path(__file__).resolve().parent
    env = dict(os.environ,
               PYTHONPATH=os.pathsep.join([str(tests), str(tests.parent), os.environ.get("PYTHONPATH", "")]))
    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "bench", "run", "--quick", "--phantoms", "sphere", "--noise", "none",
           "--n", "32", "--n-samples", "2000", "--method", "marching_cubes", "--import", "runner_plugins",
           "--out", str(out), "--jobs", "2"]
    for kind in _BROKEN_REASONS:
        cmd += ["--add-method", f"{kind}=broken_output:kind={kind}"]
    proc = subprocess.run(cmd, cwd=tests.parent, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    rows = {r["label"]: r for r in csv.DictReader(open(out / "results.csv"))}
    assert rows["marching_cubes"]["status"] == "ok"
    page = (out / "index.html").read_text()
    table = page[page.index("sphere — signed distance, clean"):]
    table = table[:table.index("</table>")]
    for kind, reason in _BROKEN_REASONS.items():
        assert rows[kind]["status"] == "invalid", (kind, rows[kind]["status"], rows[kind]["error"])
        assert rows[kind]["error"].startswith("invalid: ") and reason in rows[kind]["error"], rows[kind]["error"]
        row_html = table[table.index(f"<td>{kind}</td>"):].split("</tr>")[0]
        assert 'class="best"' not in row_html and "badge-invalid" in row_html, (kind, row_html)
        assert table.index("<td>marching_cubes</td>") < table.index(f"<td>{kind}</td>")      # validity first
    # reconstruct: the same check, exit code 1 and the reason (in-process: the plug-in registers here too)
    monkeypatch.syspath_prepend(str(tests))
    __import__("runner_plugins")
    vol = save_volume(tmp_path / "s.npz", get_phantom("sphere").volume(n=32))
    for kind, reason in _BROKEN_REASONS.items():
        capsys.readouterr()
        code = main(["reconstruct", str(vol), "--method", "broken_output", "--set", f"kind={kind}",
                     "-o", str(tmp_path / f"{kind}.ply")])
        err = capsys.readouterr().err
        assert code == 1 and "invalid mesh" in err and reason in err, (kind, code, err)


def test_with_heavy_noise_a_mesh_on_the_noisy_zero_set_is_valid_but_one_in_index_coordinates_is_not():
    """At 20 dB marching cubes follows the noisy zero set ~1 h from the truth: inaccurate, not invalid — the rule
    takes the smaller |φ| of the clean and the given volume; a shifted mesh is off both."""
    from methods import get_method
    from phantoms import add_noise, get_phantom

    clean = get_phantom("sphere").volume(n=48)
    noisy, _ = add_noise(clean, "gaussian", 20.0, seed=0)
    mesh = get_method("marching_cubes").reconstruct(noisy).mesh
    assert any(r.startswith("off the zero set") for r in check_mesh(mesh, clean))   # the clean φ alone
    assert check_mesh(mesh, clean, given=noisy) == []
    shifted = mesh.copy()
    shifted.vertices += 0.6                                     # 0.6 world units = 5.6 h off both zero sets
    assert any(r.startswith("off the zero set") for r in check_mesh(shifted, clean, given=noisy))


def test_on_a_thick_slice_input_the_zero_set_tolerance_is_in_its_slice_steps():
    import trimesh

    from phantoms import get_phantom
    from phantoms.degrade import degrade

    ph = get_phantom("sphere")
    clean = ph.volume(n=48)
    h = clean.h
    shrunk = trimesh.creation.icosphere(subdivisions=4, radius=1 - 0.7 * h)     # 0.7 h inside the truth
    thick = degrade(ph, "thick_slices@3+mask", 48)
    iso = degrade(ph, "mask", 48)
    assert any(r.startswith("off the zero set") for r in check_mesh(shrunk, clean, given=iso))
    assert not any(r.startswith("off the zero set") for r in check_mesh(shrunk, clean, given=thick))
