"""The HTML report of a run folder: ``index.html``, one self-contained file (pictures embedded as PNG).

Sections (``templates/report.html``), one module each:

0. first, which method to use per shape kind × input (:mod:`.recommend`), then the leaderboards, one verdict per
   board (:mod:`.verdicts`, :mod:`.pairwise`; a board's section: ``templates/board.html``);
1. a summary table per phantom × noise setting (× variant × N): methods as rows, metrics as columns, the best
   value per column marked (:mod:`.tables`; which is best comes from :mod:`bench.metrics.registry`);
2. per phantom, the paper's picture tables: the columns the run config's ``report`` section names (e.g.
   β = 0, β = 1, β = 1 with Gaussian noise), rows the initial surface, the kept iterations and the energy
   curve (:mod:`.paper`);
3. galleries of the other methods (the paper's "Marching Cube" and "DistMesh" tables: phantoms × clean /
   Gaussian / uniform) and the paper's uniform-noise table (:mod:`.paper`);
4. cost: time and peak memory per method per phantom, a table and a bar chart (:mod:`.cost`);
5. failed cells with their errors; 6. run metadata (:mod:`.page`, which writes the page).

Pictures are drawn by :mod:`.render` from the arrays the cells stored (:mod:`.artifacts`).
"""

from __future__ import annotations

from .cost_section import cost_section
from .page import preload, write_report
from .paper import gallery_tables, paper_layout, paper_tables
from .render import render_energy, render_mesh
from .tables import BEST_DIRECTION, summary_tables

__all__ = ["write_report", "preload", "render_mesh", "render_energy", "summary_tables", "cost_section",
           "BEST_DIRECTION", "paper_tables", "gallery_tables", "paper_layout"]
