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


@pytest.mark.heavy   # end-to-end, > 10 s: run by .ci/run's `pytest -m heavy`
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


def _launch(sync_api, p):
    return p.chromium.launch(executable_path=_chromium(), args=CHROMIUM_ARGS)


@pytest.mark.heavy   # end-to-end, > 10 s: run by .ci/run's `pytest -m heavy`
def test_method_status_and_flags_stay_in_view_at_1400_px(report, tmp_path, capsys):
    """Every summary table scrolled fully sideways in a 1,400 px window still shows its method and status
    columns (sticky), inside the window; a screenshot is kept in the test's folder."""
    sync_api = pytest.importorskip("playwright.sync_api", reason="headless browser test skipped: playwright "
                                                                 "is not installed")
    with sync_api.sync_playwright() as p:
        browser = _launch(sync_api, p)
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 900})
            page.goto(report.resolve().as_uri(), wait_until="load", timeout=120_000)
            boxes = page.evaluate("""() => Array.from(document.querySelectorAll('div.summary-wrap')).map(w => {
                w.scrollLeft = w.scrollWidth;
                const wr = w.getBoundingClientRect(), row = w.querySelector('tbody tr');
                const a = row.cells[0].getBoundingClientRect(), b = row.cells[1].getBoundingClientRect();
                return {scrolls: w.scrollWidth > w.clientWidth, left: wr.left, right: wr.right,
                        m: [a.left, a.right], s: [b.left, b.right], head: row.parentNode.parentNode
                        .tHead.rows[0].cells[1].textContent.trim()};
            })""")
            page.evaluate("document.querySelector('div.summary-wrap').scrollIntoView()")
            page.screenshot(path=str(tmp_path / "summary_1400px.png"), full_page=False)
        finally:
            browser.close()
    assert boxes
    for b in boxes:
        assert b["head"] == "status"
        assert b["left"] - 1 <= b["m"][0] and b["s"][1] <= min(b["right"], 1400) + 1, b
    with capsys.disabled():
        print(f"\n{len(boxes)} tables, {sum(b['scrolls'] for b in boxes)} scroll sideways; screenshot "
              f"{tmp_path / 'summary_1400px.png'}")


@pytest.mark.heavy
def test_a_5000_cell_report_stays_small_and_opens_a_viewer(tmp_path, capsys):
    """A synthetic dataset run of 5,010 cells (167 shapes × clean + 5 noisy seeds × 5 methods): the report is at
    most 50 MB (its time is a benchmark: tests/benchmarks/test_bench_report.py) and a table row opens its viewer."""
    import time

    from _synthetic_run import write_synthetic_run
    from bench.report import write_report

    sync_api = pytest.importorskip("playwright.sync_api", reason="headless browser test skipped: playwright "
                                                                 "is not installed")
    _chromium()
    assert write_synthetic_run(tmp_path / "run", n_shapes=167) == 5010
    t0 = time.perf_counter()
    page_path = write_report(tmp_path / "run")
    seconds = time.perf_counter() - t0
    size_mb = page_path.stat().st_size / 2 ** 20
    assert size_mb <= 50.0
    with sync_api.sync_playwright() as p:
        browser = _launch(sync_api, p)
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 900})
            page.goto(page_path.resolve().as_uri(), wait_until="load", timeout=180_000)
            rows = page.query_selector_all("tr[data-cell]")
            assert len(rows) >= 1000
            rows[-1].scroll_into_view_if_needed()
            rows[-1].click()
            page.wait_for_function("window.lsbDrawn.viewers >= 1", timeout=60_000)
            assert page.evaluate("document.querySelectorAll('#viewer canvas').length") > 0
            assert page.query_selector("#leaderboard") is not None
        finally:
            browser.close()
    with capsys.disabled():
        print(f"\n5,010-cell report: {size_mb:.1f} MB, written in {seconds:.1f} s, {len(rows)} table rows")
