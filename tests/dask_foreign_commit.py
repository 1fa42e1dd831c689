"""``--import dask_foreign_commit``: on a Dask worker, pretend the suite's checkout is at another git commit.

Imported on the client too (where it does nothing): only inside a worker process does it replace
``bench.run.provenance.git_commit``, so the client's same-code check sees a worker running other code.
"""

from __future__ import annotations

FOREIGN_COMMIT = "0123456789ab" + "0" * 28

try:
    from distributed.worker import Worker

    in_worker = bool(Worker._instances)      # the client's process holds no Worker (LocalCluster: processes)
except (ImportError, AttributeError):
    in_worker = False
if in_worker:
    import bench.run.provenance

    bench.run.provenance.git_commit = lambda: {"commit": FOREIGN_COMMIT, "dirty": False}
