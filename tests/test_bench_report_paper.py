"""The report's paper tables and galleries (bench.report.paper): columns from the run config's ``report``
section, the fallback without it, rows from the stored snapshots — on a small run folder written by hand."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from bench.report import write_report
from bench.report.artifacts import Artifacts
from bench.report.page import _load_results
from bench.report.paper import Column, gallery_tables, paper_layout, paper_tables

PAPER_SECTION = {
    "paper_columns": [
        {"title": "β = 0", "label": "sg_beta0", "noise": "none"},
        {"title": "β = 1", "label": "sg", "noise": "none"},
        {"title": "β = 1, Gaussian noise", "label": "sg", "noise": "gaussian"},
    ],
    "uniform_label": "sg",
}
# label, method, kept snapshots (None: no snapshot artifacts), last iteration
METHODS = [("sg", "shape_gradient", [0, 1, 5], 5), ("sg_beta0", "shape_gradient", [0, 1], 3),
           ("mc", "marching_cubes", None, 0)]
NOISES = [("none", None), ("gaussian", 40.0), ("uniform", 41.0)]
PHANTOMS = ["sphere", "ellipsoid"]


def _octahedron(scale: float, subdiv: int):
    """A closed mesh whose vertex count identifies the cell that stored it (through the picture caption)."""
    v = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    f = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    for _ in range(subdiv):  # split one face per step: +1 vertex, +2 faces
        a, b, c = f[0]
        v = np.vstack([v, (v[a] + v[b] + v[c]) / 3])
        n = len(v) - 1
        f = np.vstack([[[a, b, n], [b, c, n], [c, a, n]], f[1:]])
    return scale * v, f


def _write_run(out: Path, config: dict, *, parameters: str = "{}") -> dict[tuple, str]:
    """results.csv, cells/<id>.npz and run.json of a 2 phantoms × 3 noises × 3 labels run; returns the cell
    ids by (phantom, noise, label)."""
    (out / "cells").mkdir(parents=True)
    rows, ids, k = [], {}, 0
    for phantom in PHANTOMS:
        for noise, snr in NOISES:
            for label, method, snaps, last in METHODS:
                k += 1
                cid = f"{phantom}_{noise}_{label}"
                ids[(phantom, noise, label)] = cid
                v, f = _octahedron(1.0, k)                    # 6 + k vertices: unique per cell
                arrays = {"vertices": v, "faces": f, "H": np.ones(len(v))}
                if snaps is not None:
                    arrays["energy_history"] = np.linspace(2.0, 1.0, last + 1)
                    arrays["snapshot_iterations"] = np.asarray(snaps, np.int64)
                    for it in snaps:
                        arrays[f"snap{it}_vertices"] = v * (1 + 0.1 * it)
                        arrays[f"snap{it}_H"] = np.ones(len(v))
                np.savez(out / "cells" / f"{cid}.npz", **arrays)
                rows.append({"cell_id": cid, "phantom": phantom, "variant": "sdf", "N": 48, "noise": noise,
                             "snr_requested": "" if snr is None else snr, "seed": 0, "method": method,
                             "label": label, "parameters": parameters, "hausdorff": 0.01 * k,
                             "watertight": True, "euler": 2, "iterations": last,
                             "stop_reason": "converged", "wall_s": 0.1 * k, "peak_mem_mb": 10.0,
                             "status": "ok", "error": ""})
    with open(out / "results.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    (out / "run.json").write_text(json.dumps({"config": config, "cells": {"total": len(rows)}}))
    return ids


def _vertices_of(out: Path, cid: str) -> str:
    with np.load(out / "cells" / f"{cid}.npz") as z:
        return f"{len(z['vertices']):,} vertices"


@pytest.fixture()
def configured(tmp_path):
    out = tmp_path / "run"
    ids = _write_run(out, {"name": "t", "report": PAPER_SECTION})
    return out, ids


@pytest.fixture()
def bare(tmp_path):
    out = tmp_path / "run"
    ids = _write_run(out, {"name": "t"})
    return out, ids


def _tables(out: Path):
    df = _load_results(out)
    arts = Artifacts(out)
    meta = json.loads((out / "run.json").read_text())
    layout = paper_layout(meta["config"], df, arts)
    return layout, paper_tables(df, arts, layout), gallery_tables(df, arts, layout)


# ---------------------------------------------------------------------------------------------- the config's columns
def test_configured_columns_are_the_config_section_in_its_order(configured):
    out, ids = configured
    layout, tables, _ = _tables(out)
    assert layout.columns == (Column("sg_beta0", "none", "β = 0"), Column("sg", "none", "β = 1"),
                              Column("sg", "gaussian", "β = 1, Gaussian noise"))
    assert layout.uniform_labels == ("sg",)
    assert [t["phantom"] for t in tables] == PHANTOMS
    assert tables[0]["heads"] == ["β = 0 [sg_beta0]", "β = 1 [sg]", "β = 1, Gaussian noise, SNR 40 dB [sg]"]


def test_each_column_shows_the_cell_of_its_label_and_noise(configured):
    out, ids = configured
    _, tables, _ = _tables(out)
    row = next(r for r in tables[1]["rows"] if r["name"] == "Iteration 1")
    want = [ids[("ellipsoid", "none", "sg_beta0")], ids[("ellipsoid", "none", "sg")],
            ids[("ellipsoid", "gaussian", "sg")]]
    assert all(c["caption"].startswith(_vertices_of(out, cid)) for c, cid in zip(row["cells"], want))
    assert len({c["caption"] for c in row["cells"]}) == 3


def test_galleries_are_the_labels_outside_the_columns_plus_the_uniform_table(configured):
    out, _ = configured
    _, _, galleries = _tables(out)
    assert [g["title"] for g in galleries] == ["Marching Cube [mc]", "Shape gradient [sg] (β = 1) on uniform noise"]
    assert galleries[0]["heads"] == ["clean", "gaussian noise", "uniform noise"]
    assert [r["name"] for r in galleries[1]["rows"]] == ["sphere (SNR 41 dB)", "ellipsoid (SNR 41 dB)"]


def test_parameters_are_not_read(tmp_path):
    """The tables do not depend on the ``parameters`` column: the same cells with other parameters, same tables."""
    a, b = tmp_path / "a", tmp_path / "b"
    _write_run(a, {"report": PAPER_SECTION})
    _write_run(b, {"report": PAPER_SECTION}, parameters=json.dumps({"beta": 7.0, "snapshots": [2, 99]}))
    ta, tb = _tables(a)[1], _tables(b)[1]
    assert [t["heads"] for t in ta] == [t["heads"] for t in tb]
    assert [[r["name"] for r in t["rows"]] for t in ta] == [[r["name"] for r in t["rows"]] for t in tb]


# ---------------------------------------------------------------------------------------------- rows
def test_rows_are_the_kept_snapshots_and_later_rows_show_the_final_mesh(configured):
    out, _ = configured
    _, tables, _ = _tables(out)
    rows = tables[0]["rows"]
    # sg kept 0, 1, 5 and stopped at 5; sg_beta0 kept 0, 1 and stopped at 3: no "Final surface" row needed
    assert [r["name"] for r in rows] == ["Initial surface Γ₀", "Iteration 1", "Iteration 5", "Energy"]
    it5 = rows[2]["cells"]
    assert it5[0]["note"] == "final mesh: converged at iteration 3" and it5[0]["img"]
    assert it5[1]["note"] is None and it5[1]["img"]


def test_a_final_row_when_no_iteration_row_shows_the_final_mesh(tmp_path):
    out = tmp_path / "run"
    section = {"paper_columns": [{"title": "β = 0", "label": "sg_beta0", "noise": "none"}]}
    _write_run(out, {"report": section})
    _, tables, galleries = _tables(out)
    names = [r["name"] for r in tables[0]["rows"]]
    assert names == ["Initial surface Γ₀", "Iteration 1", "Final surface", "Energy"]
    assert tables[0]["rows"][2]["cells"][0]["note"] == "converged at iteration 3"
    # no uniform_label: no uniform table
    assert [g["title"] for g in galleries] == ["Shape gradient [sg]", "Marching Cube [mc]"]


# ---------------------------------------------------------------------------------------------- fallback
def test_fallback_columns_are_the_labels_with_snapshots_per_noise_in_row_order(bare):
    out, _ = bare
    layout, tables, galleries = _tables(out)
    assert layout.columns == tuple(Column(lab, nz) for nz, _ in NOISES for lab in ("sg", "sg_beta0"))
    assert layout.uniform_labels == ()
    assert tables[0]["heads"][:3] == ["sg, clean", "sg_beta0, clean", "sg, gaussian noise, SNR 40 dB"]
    assert [g["title"] for g in galleries] == ["Marching Cube [mc]"]


def test_fallback_without_snapshots_has_no_paper_tables(tmp_path):
    out = tmp_path / "run"
    _write_run(out, {})
    for p in (out / "cells").glob("*.npz"):
        with np.load(p) as z:
            arrays = {k: z[k] for k in z.files if k == "vertices" or k == "faces" or k == "H"}
        np.savez(p, **arrays)
    layout, tables, galleries = _tables(out)
    assert layout.columns == () and tables == []
    assert [g["title"] for g in galleries] == ["Shape gradient [sg]", "Shape gradient [sg_beta0]", "Marching Cube [mc]"]


# ---------------------------------------------------------------------------------------------- the page
def test_write_report_shows_the_configured_heads(configured):
    out, _ = configured
    page = write_report(out).read_text(encoding="utf-8")
    assert "<th>β = 1, Gaussian noise, SNR 40 dB [sg]</th>" in page
    assert "Shape gradient [sg] (β = 1) on uniform noise" in page
    assert page.count('<table class="pictures">') == 2 + 2   # two phantoms' paper tables, mc, uniform


def test_uniform_label_alone_keeps_the_fallback_columns(tmp_path):
    out = tmp_path / "run"
    _write_run(out, {"report": {"uniform_label": "sg"}})
    layout, _, galleries = _tables(out)
    assert len(layout.columns) == 6 and layout.uniform_labels == ("sg",)
    assert [g["title"] for g in galleries] == ["Marching Cube [mc]", "Shape gradient [sg] on uniform noise"]


def test_captions_name_each_columns_variant_and_where_a_run_stopped_early(tmp_path):
    out = tmp_path / "run"
    _write_run(out, {"name": "t", "report": PAPER_SECTION}, parameters=json.dumps({"preset": "paper"}))
    _, tables, _ = _tables(out)
    cap = tables[0]["caption"]
    assert cap.startswith("Columns drawn from sg_beta0: the paper's algorithm as printed (preset=paper); sg: the "
                          "paper's algorithm as printed")
    # sg kept iterations up to 5; sg_beta0 stopped at 3: the caption says so, and why
    assert "β = 0 stopped at iteration 3 (converged: the energy or the surface stopped changing" in cap
    assert "β = 1 stopped" not in cap


def test_a_uniform_table_of_two_labels_shows_both_side_by_side(tmp_path):
    out = tmp_path / "run"
    _write_run(out, {"name": "t", "report": dict(PAPER_SECTION, uniform_label=["sg", "sg_beta0"])})
    _, _, galleries = _tables(out)
    uni = galleries[-1]
    assert uni["title"] == "Shape gradient [sg] (β = 1) and Shape gradient [sg_beta0] (β = 0) on uniform noise"
    assert uni["heads"] == ["final mesh [sg]", "energy [sg]", "final mesh [sg_beta0]", "energy [sg_beta0]"]
    assert len(uni["rows"]) == 2 and all(len(r["cells"]) == 4 for r in uni["rows"])
