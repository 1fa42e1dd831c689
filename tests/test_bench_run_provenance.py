"""Tests of ``bench.run.provenance``: :func:`environment` (what run.json records), :func:`git_commit` of the
suite's checkout, :func:`dependency_versions` and :func:`memory_gb`."""

from __future__ import annotations

import json
import re
import subprocess
import sys

import numpy as np

from bench.run import provenance
from bench.run.provenance import SUITE_ROOT, dependency_versions, environment, git_commit, memory_gb


def test_suite_root_holds_the_packages():
    for pkg in ("bench", "methods", "phantoms", "geometry"):
        assert (SUITE_ROOT / pkg / "__init__.py").exists()


def test_git_commit_is_the_checkouts_head():
    got = git_commit()
    head = subprocess.run(["git", "-C", str(SUITE_ROOT), "rev-parse", "HEAD"], capture_output=True, text=True)
    if head.returncode != 0:
        assert got is None
        return
    assert got["commit"] == head.stdout.strip() and re.fullmatch(r"[0-9a-f]{40}", got["commit"])
    assert isinstance(got["dirty"], bool)


def test_git_commit_outside_a_checkout_is_none(tmp_path, monkeypatch):
    monkeypatch.setattr(provenance, "SUITE_ROOT", tmp_path)
    assert git_commit() is None


def test_dependency_versions_name_the_installed_ones():
    deps = dependency_versions()
    assert "levelset-bench" in deps
    assert deps["numpy"] == np.__version__


def test_environment_is_json_and_has_the_machine():
    env = environment()
    json.dumps(env)
    assert env["python"] == sys.version.split()[0]
    assert env["machine"]["cpu_count"] >= 1
    mem = memory_gb()
    assert mem is None or mem > 0
    assert env["machine"]["memory_gb"] == mem
