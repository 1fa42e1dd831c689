"""``--import dask_other_numpy``: on a Dask worker, report numpy 0.1 to ``Client.get_versions``.

Imported on the client too (where it does nothing): only inside a worker process does it change what the worker
tells the scheduler about its packages, so the client sees a worker with another numpy version.
"""

from __future__ import annotations

try:
    import distributed.versions
    from distributed.worker import Worker

    in_worker = bool(Worker._instances)      # the client's process holds no Worker (LocalCluster: processes)
except (ImportError, AttributeError):
    in_worker = False
if in_worker:
    _package_info = distributed.versions.get_package_info

    def _other_numpy(pkgs):
        return {**_package_info(pkgs), "numpy": "0.1"}

    distributed.versions.get_package_info = _other_numpy
