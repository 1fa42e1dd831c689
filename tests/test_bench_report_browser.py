"""The report in a real browser: headless Chromium (Debian's package, driven by Playwright) loads the quick grid's
report; any console error or page error fails the test; every chart must have drawn, and every summary-table row
must open its 3-D viewer (a WebGL canvas).  Skipped, with the reason printed, where Chromium or Playwright is
missing (.ci/run installs Chromium when it can).

``LSB_REPORT=path/to/index.html`` loads that report instead (e.g. the paper grid's, to measure it); the page size
and the load-event time are printed either way."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--disable-quic"]


def _chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    pytest.skip("headless browser test skipped: no Chromium on this machine (Debian: apt-get install chromium)")


@pytest.fixture(scope="module")
def report(tmp_path_factory) -> Path:
    given = os.environ.get("LSB_REPORT")
    if given:
        return Path(given)
    from bench.config import builtin_config
    from bench.report import write_report
    from bench.run import run_grid

    out = tmp_path_factory.mktemp("quick") / "run"
    run_grid(builtin_config("quick"), out, jobs=2, progress=False)
    return write_report(out)


def test_the_report_loads_without_errors_and_every_chart_and_viewer_draws(report, capsys):
    sync_api = pytest.importorskip("playwright.sync_api", reason="headless browser test skipped: playwright "
                                                                 "is not installed")
    exe = _chromium()
    size_mb = report.stat().st_size / 2 ** 20
    errors: list[str] = []
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=exe, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 900})
            page.on("console", lambda m: errors.append(f"console {m.type}: {m.text}") if m.type == "error"
                    else None)
            page.on("pageerror", lambda e: errors.append(f"page error: {e}"))
            page.goto(report.resolve().as_uri(), wait_until="load", timeout=120_000)
            load_ms = page.evaluate("performance.getEntriesByType('navigation')[0].loadEventEnd")
            n_charts = page.evaluate("document.querySelectorAll('div.chart').length")
            page.wait_for_function(f"window.lsbDrawn && window.lsbDrawn.charts >= {n_charts}", timeout=30_000)
            charts_ms = page.evaluate("window.lsbDrawn.chartsDoneMs") or load_ms
            for cid in ("claims", "summary", "charts", "paper"):
                assert page.query_selector(f"#{cid}") is not None, cid
            rows = page.query_selector_all("tr[data-cell]")
            assert rows, "no summary-table row opens a viewer"
            for i, row in enumerate(rows, 1):
                row.click()
                page.wait_for_function(f"window.lsbDrawn.viewers >= {i}", timeout=30_000)
                assert page.evaluate("document.querySelectorAll('#viewer canvas').length") > 0
                if i < len(rows):
                    page.click("#viewer-close")      # the floating viewer may cover the next row
            page.select_option("#viewer-colour", "d")           # the error map of the last cell
            page.wait_for_function(f"window.lsbDrawn.viewers >= {len(rows) + 1}", timeout=30_000)
        finally:
            browser.close()
    with capsys.disabled():
        print(f"\nreport {report}: {size_mb:.1f} MB, load event {load_ms / 1000:.2f} s, {n_charts} charts drawn "
              f"by {charts_ms / 1000:.2f} s, {len(rows)} viewers drawn")
    assert not errors, errors
    assert size_mb <= 15.0
    assert load_ms < 30_000     # a hang, not a speed test (the load time is printed above)
