"""A run's inputs, checked in one place before any executor starts: :func:`check_run_inputs`.

:func:`bench.run.run_grid` calls it first (the command line's ``--dry-run``, which runs nothing, calls it instead), so
a bad option, a folder that cannot take the run or a ``--resume`` of another grid is one :class:`InputError` line
before a process or a Dask cluster is started.  The messages name the command line's options, which the keyword
arguments of :func:`bench.run.run_grid` mirror.
"""

from __future__ import annotations

import importlib.util
import json
from dataclasses import dataclass, replace
from pathlib import Path

from phantoms import InputError

from .identity import check_same_config
from .limits import check_gb, check_seconds
from .store import check_output_dir

__all__ = ["ExecutorSpec", "check_run_inputs", "folder_config", "require_dask", "parse_scheduler_address"]

DASK_INSTALL_HINT = 'pip install -e ".[dask]"'


@dataclass(frozen=True)
class ExecutorSpec:
    """Where the cells run: ``local`` (the runner's process pool of ``jobs``) or ``dask`` (the cluster whose scheduler
    is at ``scheduler``, else a local Dask cluster of ``workers`` processes)."""

    kind: str = "local"
    scheduler: str | None = None
    workers: int | None = None


def require_dask() -> None:
    """Raise :class:`InputError` naming the extra to install when Dask's ``distributed`` is missing."""
    if importlib.util.find_spec("distributed") is None:
        raise InputError("--executor dask needs Dask's distributed scheduler, which is not installed; install it "
                         f"with: {DASK_INSTALL_HINT}")


def parse_scheduler_address(text: str) -> str:
    """``text`` as distributed reads a scheduler address (``host:port`` is ``tcp://host:port``).

    Parameters
    ----------
    text : str
        The ``--scheduler`` option, e.g. ``tcp://10.0.0.1:8786`` as ``dask scheduler`` prints it.

    Raises
    ------
    InputError
        With distributed's reason (unknown scheme, no port), or for a port out of range.
    """
    from distributed.comm.addressing import get_address_host_port, normalize_address

    try:
        address = normalize_address(text.strip())
        port = get_address_host_port(address)[1]
    except ValueError as exc:
        raise InputError(f"--scheduler: not a scheduler address: {text!r} ({exc})") from None
    if not 0 < port < 65536:
        raise InputError(f"--scheduler: port out of range in {text!r}")
    return address


def folder_config(out: Path) -> dict:
    """The config a run folder was started with (``config.json``; when that is gone — a plug-in removed it mid-run
    — the copy ``run.json`` keeps), for ``--resume``.

    Parameters
    ----------
    out : Path
        The run folder.

    Raises
    ------
    InputError
        When the folder holds no run (no ``config.json``) or the file cannot be read.
    """
    path = Path(out) / "config.json"
    kept = _run_json_config(Path(out)) if not path.exists() else None
    if kept is not None:
        return kept
    if not path.exists():
        raise InputError(f"--resume: {str(out)!r} holds no run to resume (no config.json there); check --out, or "
                         "run without --resume")
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot read {str(path)!r}: {exc}") from None
    if not isinstance(data, dict):
        raise InputError(f"cannot read {str(path)!r}: not a config (a JSON object)")
    return data


def _run_json_config(out: Path) -> dict | None:
    """The config ``run.json`` keeps (written at each session's start and end), None without one."""
    try:
        config = json.loads((out / "run.json").read_text()).get("config")
    except (OSError, ValueError, AttributeError):
        return None
    return config if isinstance(config, dict) and config else None


def _check_executor(executor, jobs: int | None, memory_gb: float | None):
    """``executor`` with its scheduler address normalised, or :class:`InputError` for options that do not fit it."""
    if not isinstance(executor, ExecutorSpec):   # None (local) or the caller's own executor object
        return executor
    if executor.kind == "local":
        for opt in ("scheduler", "workers"):
            if getattr(executor, opt) is not None:
                raise InputError(f"--{opt} needs --executor dask")
        return executor
    if executor.kind != "dask":
        raise InputError(f"--executor: unknown executor {executor.kind!r} (local or dask)")
    require_dask()
    if jobs is not None:
        raise InputError("--jobs sizes the local process pool; with --executor dask use --workers N "
                         "(local cluster) or --scheduler ADDRESS")
    if memory_gb is not None:
        raise InputError("--memory-limit applies to the local executor's cell processes; a Dask worker's memory "
                         "is limited by the cluster (dask worker --memory-limit)")
    if executor.workers is not None and executor.workers < 1:
        raise InputError("--workers must be >= 1")
    if executor.scheduler is None:
        return executor
    if executor.workers is not None:
        raise InputError("--workers sets the size of the local Dask cluster; with --scheduler the cluster's own "
                         "workers run the cells")
    return replace(executor, scheduler=parse_scheduler_address(executor.scheduler))


def check_run_inputs(cfg, out: Path | None, *, jobs: int | None = None, resume: bool = False,
                     retry_failed: bool = False, allow_mixed_code: bool = False, timeout: float | None = None,
                     method_timeout: float | None = None, score_timeout: float | None = None,
                     memory_gb: float | None = None, executor=None):
    """Check a run's inputs before anything runs; :class:`InputError` (one line) at the first problem.

    Parameters
    ----------
    cfg : bench.config.RunConfig
        The validated grid.
    out : Path or None
        The run folder: created if needed, and it must be writable, not locked by a live run, and (without
        ``resume``) hold no finished cells; with ``resume`` its ``config.json`` must give the same grid as ``cfg``.
        None: no folder (``--dry-run``).
    jobs, resume, retry_failed, allow_mixed_code, timeout, method_timeout, score_timeout, memory_gb
        As :func:`bench.run.run_grid` takes them: ``retry_failed`` and ``allow_mixed_code`` need ``resume``, the
        limits must be in range, ``jobs`` and ``memory_gb`` apply to the local executor only.
    executor : ExecutorSpec, executor object or None
        An :class:`ExecutorSpec` is checked against the options above; None or an object is taken as it is.

    Returns
    -------
    ExecutorSpec or object or None
        An :class:`ExecutorSpec` with its scheduler address normalised, or ``executor`` unchanged.
    """
    for flag, given in (("--retry-failed", retry_failed), ("--allow-mixed-code", allow_mixed_code)):
        if given and not resume:
            raise InputError(f"{flag} needs --resume")
    for opt, value in (("--timeout", timeout), ("--method-timeout", method_timeout),
                       ("--score-timeout", score_timeout)):   # before any work: no OverflowError mid-run
        check_seconds(value, opt)
    check_gb(memory_gb, "--memory-limit")
    executor = _check_executor(executor, jobs, memory_gb)
    if out is not None:
        if resume:   # before the folder is created: a mistyped --out is not left behind
            check_same_config(folder_config(Path(out)), cfg.to_dict(), str(out))
        check_output_dir(Path(out), resume)
    return executor
