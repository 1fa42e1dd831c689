"""bench.report.export: the best value bold only where unique, never for a method without an ok cell, LaTeX
escaping."""

from __future__ import annotations

from bench.report.export import group_tables, latex_text, to_latex, to_markdown
from bench.run.row import ResultRow
from bench.run.results import read_results, write_results_csv


def _frame(tmp_path, rows):
    tmp_path.mkdir(parents=True, exist_ok=True)
    write_results_csv(tmp_path, [r["cell_id"] for r in rows],
                      {r["cell_id"]: {"row": ResultRow.from_dict(r)} for r in rows})
    return read_results(tmp_path)


def _row(label, seed, status="ok", **metrics) -> dict:
    return {"cell_id": f"c_{label}_{seed}", "phantom": "sphere", "variant": "sdf", "N": 24, "noise": "gaussian",
            "snr_requested": 40.0, "seed": seed, "method": "m", "label": label, "status": status, "flags": "",
            "error": "", "fscore@h": 1.0, **metrics}                    # fscore: a tie, nobody is bold


def test_bold_marks_only_a_unique_best_of_the_valid_methods(tmp_path):
    rows = [_row("a", 0, hausdorff_h=1.0), _row("a", 1, hausdorff_h=3.0),
            _row("b", 0, hausdorff_h=2.5), _row("b", 1, hausdorff_h=2.5),
            _row("c_bad", 0, status="invalid", hausdorff_h=0.1)]
    (t,) = group_tables(_frame(tmp_path, rows), metrics=["hausdorff_h", "fscore@h"])
    assert t.frame["method"].tolist() == ["a", "b", "c_bad"] and t.frame["cells"].tolist() == ["2/2", "2/2", "0/1"]
    assert t.frame["hausdorff_h"].tolist()[:2] == [2.0, 2.5]         # mean over the seeds
    assert t.best["hausdorff_h"].tolist() == [True, False, False]    # 0.1 is invalid: never best
    assert not t.best["fscore@h"].any()
    md = to_markdown([t])
    assert "| a | 2/2 | **2** | 1 |" in md and "| c\\_bad" not in md and "| c_bad | 0/1 | – | – |" in md
    tex = to_latex([t])
    assert r"a & 2/2 & \textbf{2} & 1 \\" in tex and r"c\_bad & 0/1 & -- & -- \\" in tex


def test_latex_text_escapes_the_special_characters_and_spells_unicode_signs():
    assert latex_text("a_b&c%d$e#f{g}~^\\") == (r"a\_b\&c\%d\$e\#f\{g\}\textasciitilde{}\textasciicircum{}"
                                                 r"\textbackslash{}")
    assert latex_text("1/world units² — °") == r"1/world units$^2$ --- $^\circ$"


def test_topology_is_marked_best_only_against_a_truth(tmp_path):
    """A skull scan without truth: χ = 2 / one component is not 'best' (its reference may well have χ = 0)."""
    rows = [_row("closed", 0, euler=2, components=1, hausdorff_h=1.0, has_truth=True),
            _row("open", 0, euler=0, components=1, hausdorff_h=2.0, has_truth=True)]
    (t,) = group_tables(_frame(tmp_path / "t", rows), metrics=["euler", "hausdorff_h"])
    assert t.best["euler"].tolist() == [True, False]                 # the sphere's truth: χ = 2
    free = [dict(r, has_truth=False, hausdorff_h=None, sdf_rms_h=0.1 * (i + 1)) for i, r in enumerate(rows)]
    (t,) = group_tables(_frame(tmp_path / "f", free), metrics=["euler", "components", "sdf_rms_h"])
    assert not t.best["euler"].any() and not t.best["components"].any()
    assert t.best["sdf_rms_h"].tolist() == [True, False]              # the truth-free metrics still mark
