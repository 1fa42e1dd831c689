"""bench.run.audit: the sealed cell records are the truth of a run folder — the problems of its tables against
them, the records the runner sets aside, the one-time sealing of a folder written before seals."""

from __future__ import annotations

import json

import pytest

from _synthetic_run import write_synthetic_run
from bench.run.audit import REJECTED, check_run_folder, refuse_damaged, seal_unsealed, set_aside
from bench.run.integrity import record_problem
from phantoms import InputError


@pytest.fixture
def run(tmp_path):
    out = tmp_path / "run"
    write_synthetic_run(out, n_shapes=1, seeds=1, noise=("none",), sealed=True)     # 5 cells
    return out


def _records(out):
    return {p.stem: json.loads(p.read_text()) for p in sorted((out / "cells").glob("*.json"))}


def test_an_intact_folder_has_no_problem_and_is_not_refused(run):
    assert check_run_folder(run) == [] and check_run_folder(run, arrays=False) == []
    refuse_damaged(run, [])


def test_refusal_is_one_line_naming_the_first_problems_and_the_way_out(run):
    with pytest.raises(InputError) as err:
        refuse_damaged(run, [f"cell_{i}: no row in results.csv" for i in range(12)], ", or else")
    text = str(err.value)
    assert "\n" not in text and "cell_7: no row" in text and "cell_8" not in text and "... 4 more" in text
    assert f"python -m bench run --resume --out {run}" in text and text.endswith(", or else")


def test_set_aside_keeps_the_records_the_runner_knows_and_renames_any_other(run):
    records = _records(run)
    known = {cid: rec["checksum"] for cid, rec in records.items()}
    first, second = sorted(records)[:2]
    forged = dict(records[second], row={**records[second]["row"], "hausdorff_h": 0.0})
    (run / "cells" / f"{second}.json").write_text(json.dumps(forged))      # changed during the run
    (run / "cells" / "extra.json").write_text(json.dumps(records[first]))  # a copy under another name
    assert sorted(set_aside(run, known)) == sorted([second, "extra"])
    assert (run / "cells" / f"extra.json{REJECTED}").exists() and (run / "cells" / f"{second}.json{REJECTED}").exists()
    assert sorted(p.stem for p in (run / "cells").glob("*.json")) == sorted(set(records) - {second})


def test_seal_unsealed_seals_only_the_records_that_agree_with_the_tables(run):
    records = _records(run)
    a, b, c = sorted(records)[:3]
    for cid in (a, b):
        rec = dict(records[cid])
        del rec["checksum"]
        if cid == b:
            rec["row"] = {**rec["row"], "hausdorff_h": 0.0}                  # edited: disagrees with results.csv
        (run / "cells" / f"{cid}.json").write_text(json.dumps(rec))
    assert [p.split(" ")[0] for p in check_run_folder(run)] == [f"cells/{a}.json", f"cells/{b}.json"]
    assert seal_unsealed(run) == ([a], [b])
    sealed = json.loads((run / "cells" / f"{a}.json").read_text())
    assert record_problem(sealed, run / "cells" / f"{a}.npz") is None and "sealed_later" in sealed["checksum"]
    assert json.loads((run / "cells" / f"{c}.json").read_text()) == records[c]     # a sealed one: untouched
    problems = check_run_folder(run)
    assert len(problems) == 1 and problems[0].startswith(f"cells/{b}.json has no seal")


def test_a_metric_added_after_the_run_is_not_a_damage_but_a_column_the_records_carry_is(run, monkeypatch):
    import bench.metrics as metrics

    monkeypatch.setattr(metrics, "METRIC_NAMES", (*metrics.METRIC_NAMES, "a_metric_of_a_later_version"))
    assert check_run_folder(run, arrays=False) == []            # the run predates it: no record carries it
    import csv

    rows = list(csv.reader(open(run / "results.csv", newline="")))
    col = rows[0].index("hausdorff_h")
    with open(run / "results.csv", "w", newline="") as fh:
        csv.writer(fh).writerows([r[:col] + r[col + 1:] for r in rows])
    assert any("lacks column 'hausdorff_h'" in p for p in check_run_folder(run, arrays=False))


def test_an_altered_npz_is_a_problem_and_a_stray_copy_only_a_warning(run):
    import numpy as np

    first = sorted((run / "cells").glob("*.json"))[0]
    (run / "cells" / "copy_of_first.json").write_text(first.read_text())        # a stray copy
    said = []
    assert check_run_folder(run, warn=said.append) == []
    assert len(said) == 1 and "copy_of_first.json claims cell" in said[0] and said[0].endswith("ignored)")
    npz = first.with_suffix(".npz")
    with np.load(npz) as z:
        arrays = {k: z[k] for k in z.files}
    np.savez(npz, **{**arrays, "vertices": arrays["vertices"] * 1.01})         # loads fine, not what was sealed
    problems = check_run_folder(run, warn=said.append)
    assert len(problems) == 1 and problems[0].startswith(f"cells/{first.stem}.json has altered arrays")
