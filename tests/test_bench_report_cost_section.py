"""The report's cost section (bench.report.cost_section): mean time and memory per method and phantom."""

from __future__ import annotations

import numpy as np
import pandas as pd

from bench.report import cost_section


def test_cost_section_table_and_chart():
    rows = []
    for ph in ("sphere", "ellipsoid"):
        for lab, t, m in (("marching_cubes", 0.1, 5.0), ("shape_gradient", 2.0, 30.0)):
            for noise in ("none", "gaussian"):
                rows.append({"phantom": ph, "N": 48, "label": lab, "status": "ok", "noise": noise,
                             "wall_s": t * (2 if noise == "gaussian" else 1), "peak_mem_mb": m})
    rows.append({"phantom": "sphere", "N": 48, "label": "distmesh", "status": "failed", "noise": "none",
                 "wall_s": np.nan, "peak_mem_mb": np.nan})
    sec = cost_section(pd.DataFrame(rows))
    assert sec["n_cells"] == 8
    assert sec["chart"].startswith("data:image/svg+xml;base64,")
    import base64

    svg = base64.b64decode(sec["chart"].split(",", 1)[1]).decode()
    assert svg.count("<rect x=") >= 2 * 4 and "marching_cubes: 0.15" in svg and "time (s)" in svg
    h = sec["html"]
    assert h.count("<tr><td>") == 2 and "distmesh" not in h          # failed cells have no cost
    assert "sphere" in h and "ellipsoid" in h and "time (s)" in h and "memory (MiB)" in h
    assert "0.15" in h and "<td>3</td>" in h                         # means over the noise settings
    assert h.count('class="best"') == 4                                # lowest time and memory per phantom
    assert cost_section(pd.DataFrame(rows[-1:]))["n_cells"] == 0
