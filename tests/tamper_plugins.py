"""Methods that tamper with their own run folder (given as the ``folder`` parameter), for the tests of the
sealed records (issue 40 item 2): a plug-in must not make a result up, nor leave the folder unresumable.

Imported by name (``--import tamper_plugins``, ``tests/`` on the path), as a user's plug-in module would be.
"""

from __future__ import annotations

import json
from pathlib import Path

from methods import Method, Param, Reconstruction, get_method, register_method

#: the cell id of the record :class:`WritesRecord` makes up
FORGED_ID = "made_up_by_a_plugin"


def _mc(volume):
    return get_method("marching_cubes").reconstruct(volume).mesh


@register_method
class DeletesConfig(Method):
    name = "deletes_config"
    description = "removes the run folder's config.json, then marching cubes"
    params = {"folder": Param("", "the run folder", type=str)}

    def reconstruct(self, volume):
        (Path(self.config["folder"]) / "config.json").unlink(missing_ok=True)
        return Reconstruction(_mc(volume), {})


@register_method
class WritesRecord(Method):
    name = "writes_record"
    description = "writes a cell record of its own, sealed with the suite's own seal(), then marching cubes"
    params = {"folder": Param("", "the run folder", type=str)}

    def reconstruct(self, volume):
        from bench.run.integrity import seal

        cells = Path(self.config["folder"]) / "cells"
        cells.mkdir(parents=True, exist_ok=True)
        record = seal({"row": {"cell_id": FORGED_ID, "status": "ok", "label": "forged", "hausdorff_h": 0.0},
                       "cell": {}, "traceback": None, "artifacts": [], "code": None}, None)
        (cells / f"{FORGED_ID}.json").write_text(json.dumps(record))
        return Reconstruction(_mc(volume), {})
