"""How to run a grid, as one typed value: :class:`RunOptions`, what :func:`bench.run.run_grid` takes beside the
config and the folder, handed whole to the stages of a run instead of a dozen keyword arguments through each.

A run's limits come from the options and the config together: :func:`time_limits` and :func:`memory_limit` (an
option left None takes the config's value; 0 means none).
"""

from __future__ import annotations

from dataclasses import dataclass

from .limits import TimeLimits, default_memory_gb

__all__ = ["RunOptions", "memory_limit", "time_limits"]


@dataclass(frozen=True)
class RunOptions:
    """The options of a grid run (:func:`bench.run.run_grid`); every one has the default the command line has.

    Parameters
    ----------
    jobs : int, optional
        Cells at once with the local executor (default: the CPU count).
    resume : bool
        Skip the cells already finished in the folder; its config must give the same grid and its cells must come
        from the same code (unless ``allow_mixed_code``).
    retry_failed : bool
        With ``resume``: run the failed and timed-out cells again.
    timeout, method_timeout, score_timeout : float, optional
        Seconds per cell, per method run and per scoring (None: the config's, 0: none; :mod:`bench.run.limits`).
    memory_gb : float, optional
        Address space of each local cell process in GB (None: the config's ``run.memory_limit``, else 75 % of
        the physical memory divided by ``jobs``; 0: none).
    save_meshes : bool
        Also write each cell's final mesh as a PLY file.
    progress : bool, optional
        Show a progress bar (default: when stderr is a terminal, else plain progress lines; False: neither).
    argv : list of str, optional
        The command line recorded in run.json (default: this process's).
    executor : bench.run.inputs.ExecutorSpec or object, optional
        An :class:`~bench.run.inputs.ExecutorSpec` (``dask``: the runner starts the cluster after the checks and
        closes it), or any object with ``run(cells, on_start, on_result)``; default the local process pool.
    allow_mixed_code : bool
        With ``resume``: accept cells written by other code.
    force : bool
        Run the cells whose method's cost estimate exceeds their time limit (also the config's ``run.force``);
        otherwise they are failed rows at once (:mod:`bench.run.estimate`).
    """

    jobs: int | None = None
    resume: bool = False
    retry_failed: bool = False
    timeout: float | None = None
    method_timeout: float | None = None
    score_timeout: float | None = None
    memory_gb: float | None = None
    save_meshes: bool = False
    progress: bool | None = None
    argv: list[str] | None = None
    executor: object = None
    allow_mixed_code: bool = False
    force: bool = False

    def input_checks(self) -> dict:
        """The options :func:`bench.run.inputs.check_run_inputs` checks, as its keyword arguments."""
        return dict(jobs=self.jobs, resume=self.resume, retry_failed=self.retry_failed,
                    allow_mixed_code=self.allow_mixed_code, timeout=self.timeout, method_timeout=self.method_timeout,
                    score_timeout=self.score_timeout, memory_gb=self.memory_gb, executor=self.executor)


def time_limits(cfg, timeout: float | None = None, method_timeout: float | None = None,
                score_timeout: float | None = None) -> TimeLimits:
    """The run's :class:`TimeLimits`: each argument overrides the config's (None: the config's, 0: none).

    Parameters
    ----------
    cfg : bench.config.RunConfig
        The validated grid configuration.
    timeout, method_timeout, score_timeout : float, optional
        Seconds per cell, per method run and per scoring.
    """
    def pick(arg, conf):
        return conf if arg is None else (arg or None)

    return TimeLimits(pick(timeout, cfg.timeout), pick(method_timeout, cfg.method_timeout),
                      pick(score_timeout, cfg.score_timeout))


def memory_limit(cfg, memory_gb: float | None, jobs: int) -> float | None:
    """GB of address space per cell process: ``memory_gb`` (None: the config's ``run.memory_limit``; absent
    there too: :func:`bench.run.limits.default_memory_gb` of ``jobs``), None for no limit (0).

    Parameters
    ----------
    cfg : bench.config.RunConfig
        The validated grid configuration.
    memory_gb : float or None
        The option's value.
    jobs : int
        Cells at once.
    """
    value = cfg.memory_limit if memory_gb is None else memory_gb
    if value is None:
        return default_memory_gb(jobs)
    return float(value) or None
