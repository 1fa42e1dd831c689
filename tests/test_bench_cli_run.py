"""`python -m bench run`: the quick grid through the CLI, failure isolation, timeouts, resume, bad input."""

from __future__ import annotations

import csv
import json
import re
import math
import os
import signal
import subprocess
import sys
import time
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from bench.cli import main
from bench.config import builtin_config
from bench.specs import parse_method_spec
from bench.run import expand_grid

from bench.metrics import METRIC_NAMES

REPO = Path(__file__).resolve().parent.parent
TESTS = Path(__file__).resolve().parent
# the quick grid plus one method that always raises (registered by tests/runner_plugins.py in every worker)
QUICK_ARGS = ["--quick", "--import", "runner_plugins", "--add-method", "failing", "--jobs", "2"]
# columns that measure the machine, not the result
COST_COLUMNS = {"wall_s", "peak_mem_mb"}


def _env() -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(TESTS), str(REPO)] + [p for p in [env.get("PYTHONPATH")] if p])
    env["PYTHONWARNINGS"] = "ignore"
    return env


def _bench(*args, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "bench", "run", *args], cwd=REPO, env=_env(),
                          capture_output=True, text=True, timeout=300, **kw)


def _rows(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("quick") / "run"
    t0 = time.perf_counter()
    proc = _bench(*QUICK_ARGS, "--out", str(out))
    proc.wall_s = time.perf_counter() - t0
    assert proc.returncode == 0, proc.stderr[-3000:]
    return out, proc


# ---------------------------------------------------------------------------------------------- the quick run
def test_quick_results_csv_has_a_row_per_cell_with_every_metric(quick_run):
    out, proc = quick_run
    sys.path.insert(0, str(TESTS))
    try:
        import runner_plugins  # noqa: F401  (registers "failing" for the in-process grid expansion)
    finally:
        sys.path.remove(str(TESTS))
    cfg = builtin_config("quick")
    cfg.methods.append(parse_method_spec("failing"))
    cells = expand_grid(cfg)
    rows = _rows(out / "results.csv")
    assert [r["cell_id"] for r in rows] == [c.cell_id for c in cells]
    header = list(rows[0])
    for col in ["cell_id", "phantom", "variant", "N", "noise", "snr_requested", "snr_achieved", "seed", "method",
                "parameters", *METRIC_NAMES, "status", "error"]:
        assert col in header, col
    assert header[-2:] == ["status", "error"]
    assert "cells: " in proc.stdout and "failed" in proc.stdout  # the summary line


def test_a_failing_method_is_a_failed_row_and_the_others_finish(quick_run):
    out, _ = quick_run
    rows = _rows(out / "results.csv")
    failing = [r for r in rows if r["method"] == "failing"]
    others = [r for r in rows if r["method"] != "failing"]
    assert failing and all(r["status"] == "failed" for r in failing)
    assert all("deliberate failure" in r["error"] for r in failing)
    assert all(r["hausdorff"] == "" for r in failing)
    assert others and all(r["status"] == "ok" for r in others), [(r["cell_id"], r["error"]) for r in others]
    for r in others:
        assert math.isfinite(float(r["hausdorff"])) and float(r["hausdorff"]) >= 0
        assert r["watertight"] in ("True", "False")
        assert float(r["wall_s"]) > 0
        assert json.loads(r["parameters"])  # the method's full parameter set
        if r["noise"] == "gaussian":
            assert abs(float(r["snr_achieved"]) - float(r["snr_requested"])) < 0.5
    # the failed cell keeps its traceback on disk
    rec = json.loads((out / "cells" / f"{failing[0]['cell_id']}.json").read_text())
    assert "RuntimeError" in rec["traceback"]


class _Page(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.summary_titles: list[str] = []
        self.images = 0
        self.tables = 0
        self.best = 0
        self._in_title = False

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "h3" and "summary-title" in (a.get("class") or ""):
            self._in_title = True
            self.summary_titles.append("")
        if tag == "img" and (a.get("src") or "").startswith(("data:image/webp;base64,", "data:image/png;base64,",
                                                              "data:image/svg+xml;base64,")):
            self.images += 1
        if tag == "table":
            self.tables += 1
        if tag == "span" and a.get("class") == "best":
            self.best += 1

    def handle_endtag(self, tag):
        if tag == "h3":
            self._in_title = False

    def handle_data(self, data):
        if self._in_title:
            self.summary_titles[-1] += data


def test_index_html_has_a_summary_table_per_phantom_and_noise_and_pictures(quick_run):
    out, _ = quick_run
    page = _Page()
    page.feed((out / "index.html").read_text(encoding="utf-8"))
    page.close()
    titles = page.summary_titles
    for phantom in ("sphere", "ellipsoid"):
        assert any(t.startswith(f"{phantom} — signed distance, clean") for t in titles), titles
        assert any(t.startswith(f"{phantom} — signed distance, gaussian noise") for t in titles), titles
    assert len(titles) == 4
    assert page.images >= 1
    assert page.best >= 4  # a best value marked in every summary table
    html = (out / "index.html").read_text(encoding="utf-8")
    assert "deliberate failure" in html  # the failed-cells section
    # self-contained: nothing to fetch — no script, style or image from elsewhere (plotly.js, embedded, mentions
    # URLs in its own code: the markup outside the scripts must not)
    outside_scripts = re.sub(r"<script[^>]*>.*?</script>", "", html, flags=re.S)
    assert "http://" not in outside_scripts and "https://" not in outside_scripts
    assert not re.search(r"<script[^>]*\bsrc=", html) and "@import" not in html


def test_run_json_records_config_versions_machine_and_time(quick_run):
    out, _ = quick_run
    meta = json.loads((out / "run.json").read_text())
    assert meta["config"]["name"] == "quick*"  # the quick grid, changed on the command line (--add-method)
    assert "--add-method" in meta["config"]["description"]
    assert meta["python"].count(".") == 2
    assert meta["dependencies"]["numpy"] and "trimesh" in meta["dependencies"]
    assert meta["machine"]["cpu_count"] >= 1
    assert meta["total_s"] > 0 and meta["start"] and meta["end"]
    assert meta["cells"]["finished"] == meta["cells"]["total"]
    assert "git" in meta


# ---------------------------------------------------------------------------------------------- resume
def _finished(out: Path) -> list[Path]:
    """The finished cells' records (pathlib's glob also matches the hidden temporary files being written)."""
    return [p for p in (out / "cells").glob("*.json") if not p.name.startswith(".")]


@pytest.mark.heavy
def test_interrupted_run_resumes_to_the_same_results(quick_run, tmp_path):
    """Kill the run after its first finished cell, rerun with --resume: the same rows as the uninterrupted run."""
    reference, _ = quick_run
    out = tmp_path / "run"
    args = [*QUICK_ARGS, "--phantoms", "sphere", "--out", str(out)]  # a sub-grid of the reference run
    proc = subprocess.Popen([sys.executable, "-m", "bench", "run", *args], cwd=REPO, env=_env(),
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and not _finished(out) and proc.poll() is None:
            time.sleep(0.05)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    done = _finished(out)
    assert 1 <= len(done) < 8, "the run should have been interrupted after its first cell"

    # no grid options: --resume takes the grid from the folder's config.json
    res = _bench("--resume", "--out", str(out), "--jobs", "2", "--no-report")
    assert res.returncode == 0, res.stderr[-3000:]
    assert "already done" in res.stdout
    rows = _rows(out / "results.csv")
    ref = {r["cell_id"]: r for r in _rows(reference / "results.csv")}
    assert len(rows) == 8
    for r in rows:
        expected = ref[r["cell_id"]]
        for col, value in r.items():
            if col not in COST_COLUMNS:
                assert value == expected[col], (r["cell_id"], col, value, expected[col])


# ---------------------------------------------------------------------------------------------- isolation
@pytest.mark.heavy   # end to end, ~10 s: run by .ci/run's second pytest
def test_timeout_and_crash_are_rows_and_the_run_goes_on(tmp_path):
    out = tmp_path / "run"
    res = _bench("--quick", "--phantoms", "sphere", "--noise", "none", "--n", "16", "--n-samples", "2000",
                 "--import", "runner_plugins", "--method", "sleepy:seconds=60", "--add-method", "crashing",
                 "--add-method", "marching_cubes", "--timeout", "2", "--jobs", "2", "--no-report",
                 "--save-meshes", "--out", str(out))
    assert res.returncode == 0, res.stderr[-3000:]
    status = {r["method"]: (r["status"], r["error"]) for r in _rows(out / "results.csv")}
    assert status["sleepy"][0] == "timeout" and "2 s" in status["sleepy"][1]
    assert status["crashing"][0] == "failed" and "SIGKILL" in status["crashing"][1]
    assert status["marching_cubes"][0] == "ok"
    assert "1 ok, 1 failed, 1 timeout" in res.stdout
    ok = [r for r in _rows(out / "results.csv") if r["status"] == "ok"]
    meshes = sorted(p.name for p in (out / "meshes").iterdir())
    assert meshes == [f"{ok[0]['cell_id']}.ply"]  # --save-meshes: DIR/meshes/<cell_id>.ply
    import trimesh

    mesh = trimesh.load(out / "meshes" / meshes[0])
    assert len(mesh.faces) == int(ok[0]["n_faces"]) and mesh.is_watertight


# ---------------------------------------------------------------------------------------------- bad input
@pytest.mark.parametrize("args, message", [
    (["--quick", "--phantoms", "nosuch"], "unknown phantom 'nosuch'"),
    (["--quick", "--method", "nosuch"], "unknown method 'nosuch'"),
    (["--quick", "--method", "marching_cubes:nosuch=1"], "no parameter 'nosuch'"),
    (["--quick", "--method", "marching_cubes:step_size=abc"], "step_size"),
    (["--quick", "--noise", "pink"], "unknown noise kind 'pink'"),
    (["--quick", "--import", "no_such_module_xyz"], "no_such_module_xyz"),
])
def test_bad_command_line_exits_2(args, message, tmp_path, capsys):
    assert main(["run", *args, "--out", str(tmp_path / "o"), "--dry-run"]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("phantom, message", [
    ("volume:{tmp}/empty.nii.gz?labels=all", "the image holds no label (every voxel is 0)"),
    ("field:sphere", "the field's protocol takes a mesh phantom"),
    ("field:bunny?scale=1.5&scale=2", "option 'scale' is given twice"),
])
def test_a_phantom_that_cannot_run_is_refused_at_dry_run_in_one_line(phantom, message, tmp_path, capsys):
    import nibabel as nib
    import numpy as np

    nib.save(nib.Nifti1Image(np.zeros((12, 12, 12), np.int16), np.eye(4)), str(tmp_path / "empty.nii.gz"))
    assert main(["run", "--quick", "--noise", "none", "--phantoms", phantom.format(tmp=tmp_path),
                 "--method", "marching_cubes", "--dry-run"]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and message in err[0], captured
    assert " cells (" not in captured.out


@pytest.mark.parametrize("text, message", [
    ("[grid\nphantoms = ", "not valid TOML"),
    ('[grid]\nphantoms = ["sphere"]\n[[methods]]\nname = "marching_cubes"\nparams = { nosuch = 1 }\n', "nosuch"),
    ('[grid]\nphantoms = ["sphere"]\ncolour = 1\n[[methods]]\nname = "marching_cubes"\n', "unknown key 'colour'"),
    ('[grid]\nphantoms = ["sphere"]\nnoise = [{ kind = "gaussian", snr = "loud" }]\n'
     '[[methods]]\nname = "marching_cubes"\n', "snr"),
    ('[grid]\nphantoms = ["torus_knot"]\n[[methods]]\nname = "marching_cubes"\n', "unknown phantom"),
])
def test_bad_config_exits_2(text, message, tmp_path, capsys):
    path = tmp_path / "grid.toml"
    path.write_text(text)
    assert main(["run", "--config", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()


def test_unwritable_or_occupied_output_folder_exits_2(tmp_path, capsys, quick_run):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    assert main(["run", "--quick", "--out", str(blocker / "sub")]) == 2
    assert "not writable" in capsys.readouterr().err
    reference, _ = quick_run  # a folder that already holds a run needs --resume
    assert main(["run", "--quick", "--out", str(reference)]) == 2
    assert "--resume" in capsys.readouterr().err
    assert main(["run", "--config", str(tmp_path / "missing.toml")]) == 2
    assert "cannot read config" in capsys.readouterr().err
    assert main(["report", str(tmp_path)]) == 2
    assert "not a run folder" in capsys.readouterr().err


def test_a_run_and_its_resume_show_progress_with_a_time_estimate_when_not_on_a_terminal(tmp_path):
    out = tmp_path / "run"
    args = ["--quick", "--phantoms", "sphere,ellipsoid,torus,cylinder,fused_spheres", "--n", "16",
            "--degrade", "none,mask", "--noise", "none", "--method", "marching_cubes", "--method", "mc_taubin",
            "--no-report", "--jobs", "2", "--out", str(out)]
    proc = _bench(*args)
    assert proc.returncode == 0, proc.stderr[-3000:]
    lines = [ln for ln in proc.stderr.splitlines() if ln.startswith("progress:")]
    assert lines[0] == "progress: 0/20 cells done, 20 to run"
    assert any(re.fullmatch(r"progress: \d+/20 cells, 0 not ok, about [\d.]+ (s|min) left "
                    r"\([\d.]+ (s|min)–[\d.]+ (s|min)\)", ln) for ln in lines), lines
    assert lines[-1] == "progress: 20/20 cells, 0 not ok"
    records = sorted((out / "cells").glob("*.json"))
    for rec in records[:8]:                                    # an interrupted run: 8 cells never finished
        rec.unlink()
    proc = _bench("--resume", "--no-report", "--out", str(out))
    assert proc.returncode == 0, proc.stderr[-3000:]
    lines = [ln for ln in proc.stderr.splitlines() if ln.startswith("progress:")]
    assert lines[0] == "progress: 12/20 cells done, 8 to run" and lines[-1] == "progress: 20/20 cells, 0 not ok"
    assert any("left" in ln for ln in lines), lines


def test_a_write_error_advises_what_its_cause_needs():
    import errno

    from bench.cli.run import _write_advice
    from geometry.files import WriteError

    advice = {code: _write_advice(WriteError("/r/cells/x.json", os.strerror(code)))
              for code in (errno.ENOSPC, errno.EACCES, errno.EEXIST, errno.ENOTDIR)}
    assert advice == {errno.ENOSPC: "free space", errno.EACCES: "fix the permissions", errno.EEXIST: "fix that",
                      errno.ENOTDIR: "fix that"}

def test_a_grid_changed_on_the_command_line_is_a_custom_run_described_by_its_own_grid(tmp_path):
    """--phantoms on the paper's config: not titled or described as the paper's experiment."""
    from bench.cli import build_parser
    from bench.cli.run import _resolve_config

    args = build_parser().parse_args(["run", "--phantoms", "sphere,torus", "--noise", "none,gaussian@30",
                                      "--n", "24", "--method", "marching_cubes", "--dry-run"])
    cfg = _resolve_config(args)
    assert cfg.name == "custom run"
    assert "paper's experiment" not in cfg.description
    assert cfg.description.startswith("A custom run: 2 phantom specs (sphere, torus) × 2 noise settings "
                                      "(none, gaussian@30) at N = 24, seed 0; 1 method (marching_cubes).")
    assert "'paper' config" in cfg.description and "--phantoms" in cfg.description
    # methods alone changed: still the config's grid, its name starred
    args = build_parser().parse_args(["run", "--quick", "--add-method", "flying_edges", "--dry-run"])
    assert _resolve_config(args).name == "quick*"


def _label_map(folder) -> str:
    import nibabel as nib

    lab = np.zeros((20, 20, 20), np.uint8)
    lab[3:9, 3:9, 3:9] = 1
    lab[11:17, 11:17, 11:17] = 3
    path = folder / "seg.nii.gz"
    nib.save(nib.Nifti1Image(lab, np.eye(4)), str(path))
    return str(path)


def test_a_labels_list_on_the_command_line_keeps_its_commas(tmp_path):
    from bench.cli.run import split_phantom_list

    seg = _label_map(tmp_path)
    assert split_phantom_list(f"volume:{seg}?labels=1,3,sphere, torus") == [f"volume:{seg}?labels=1,3", "sphere",
                                                                            "torus"]
    assert split_phantom_list("sphere,torus") == ["sphere", "torus"]
    assert split_phantom_list(f"volume:{seg}?labels=1,3,volume:{seg}?label=3") == [f"volume:{seg}?labels=1,3",
                                                                                  f"volume:{seg}?label=3"]
    res = subprocess.run([sys.executable, "-m", "bench", "run", "--phantoms", f"volume:{seg}?labels=1,3",
                          "--method", "marching_cubes", "--noise", "none", "--dry-run"],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    assert "seg_label1_" in res.stdout and "seg_label3_" in res.stdout and "2 cells" in res.stdout


def test_an_absent_label_is_refused_at_dry_run_and_before_any_cell(tmp_path):
    seg = _label_map(tmp_path)
    for extra in (["--dry-run"], ["--out", str(tmp_path / "run")]):
        res = subprocess.run([sys.executable, "-m", "bench", "run", "--phantoms", f"volume:{seg}?label=4",
                              "--method", "marching_cubes", "--noise", "none", "--n", "16", *extra],
                             capture_output=True, text=True, timeout=120)
        assert res.returncode == 2 and "label 4 does not occur in the image; labels present: 1, 3" in res.stderr
        assert res.stderr.count("\n") == 1 and not (tmp_path / "run" / "cells").exists()
