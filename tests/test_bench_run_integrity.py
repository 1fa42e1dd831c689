"""Tests of ``bench.run.integrity``: :func:`seal` and :func:`record_problem` find an altered record, altered or
missing arrays, and call a record without a checksum unsealed (altered, not "older"); :func:`file_sha256`."""

from __future__ import annotations

import hashlib
import json

import numpy as np

from bench.run.integrity import UNSEALED, file_sha256, record_problem, seal
from bench.run.values import plain


def _written(tmp_path, record, with_npz=True):
    npz = tmp_path / "cell.npz"
    if with_npz:
        np.savez(npz, a=np.arange(5))
    sealed = seal(record, npz if with_npz else None)
    (tmp_path / "cell.json").write_text(json.dumps(sealed, default=plain))   # as the store writes it
    return json.loads((tmp_path / "cell.json").read_text()), npz


def test_a_sealed_record_reads_back_clean_even_with_numpy_values_and_nan(tmp_path):
    rec, npz = _written(tmp_path, {"row": {"h": np.float64(0.2), "n": np.int64(3), "x": float("nan")}})
    assert set(rec["checksum"]) == {"record", "npz"}
    assert record_problem(rec, npz) is None


def test_an_edited_record_and_altered_or_missing_arrays_are_found(tmp_path):
    rec, npz = _written(tmp_path, {"row": {"hausdorff": 0.1}})
    edited = {**rec, "row": {"hausdorff": 0.05}}
    assert "altered after it was written" in record_problem(edited, npz)
    np.savez(npz, a=np.arange(6))
    assert record_problem(rec, npz) == "has altered arrays: cell.npz does not match its checksum"
    npz.unlink()
    assert record_problem(rec, npz) == "lost its arrays: cell.npz is missing"


def test_a_record_without_checksum_is_unsealed_and_one_without_arrays_needs_none(tmp_path):
    assert record_problem({"row": {}}, tmp_path / "x.npz") == UNSEALED
    assert "checksum was removed" in UNSEALED
    rec, npz = _written(tmp_path, {"row": {}}, with_npz=False)
    assert rec["checksum"]["npz"] is None and record_problem(rec, npz) is None
    assert "altered" in record_problem({**rec, "checksum": "junk"}, npz)


def test_file_sha256(tmp_path):
    p = tmp_path / "f.bin"
    p.write_bytes(b"abc" * 1000)
    assert file_sha256(p) == hashlib.sha256(b"abc" * 1000).hexdigest()
    assert file_sha256(tmp_path / "missing") is None


def test_without_an_npz_path_only_the_record_is_checked(tmp_path):
    rec, npz = _written(tmp_path, {"row": {"hausdorff": 0.1}})
    npz.unlink()
    assert record_problem(rec, None) is None                       # what table / compare need
    assert "altered" in record_problem({**rec, "row": {"hausdorff": 0.2}}, None)
