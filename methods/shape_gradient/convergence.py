"""The flow's stop tests and its stages: when an iteration counts as converged, and what the flow does next when
it has settled (the next stage's settings, or the end of the run)."""

from __future__ import annotations

from .settings import Stage

__all__ = ["ConvergenceTest", "Stages", "PATIENCE"]

PATIENCE = 3     # consecutive iterations a stop test must hold


class ConvergenceTest:
    """The two ``converged`` tests: the relative energy change below ``tol``, or the largest normal move below
    ``move_tol`` (world units), for :data:`PATIENCE` consecutive iterations (0 = that test off).

    ``held``: no test counts until the next mesh change (:meth:`reset`) — a start kept unremeshed (marching
    cubes' slivers) moves slowly until a remesh, which is no convergence.
    """

    def __init__(self, tol: float, move_tol: float, move_tol_voxels: float):
        self.tol, self.move_tol, self.move_tol_voxels = float(tol), float(move_tol), float(move_tol_voxels)
        self.flat_energy = self.small_move = 0      # consecutive iterations below tol / move_tol
        self.held = False

    def reset(self, held: bool | None = None) -> None:
        """A new mesh or stage: the tests count afresh; ``held`` (when given) says whether they count at all until
        the next reset."""
        self.flat_energy = self.small_move = 0
        if held is not None:
            self.held = held

    def observe(self, rel: float, move: float) -> str | None:
        """Count one iteration of relative energy change ``rel`` and largest normal move ``move`` (world units);
        the reason (a sentence) when a test has held for :data:`PATIENCE` iterations, else None."""
        if self.held:
            self.flat_energy = self.small_move = 0
        else:
            self.flat_energy = self.flat_energy + 1 if rel < self.tol else 0
            self.small_move = self.small_move + 1 if move < self.move_tol else 0
        if self.flat_energy >= PATIENCE:
            return f"relative energy change below tol = {self.tol:g} for {PATIENCE} iterations"
        if self.small_move >= PATIENCE:
            return f"largest normal move below move_tol = {self.move_tol_voxels:g} voxels for {PATIENCE} iterations"
        return None


class Stages:
    """The stages of one flow, first first: the current one's β and edge length, and where each began
    (``info['stages']``).

    Parameters
    ----------
    stages : sequence of Stage
        The stages (at least one); the first is entered at once, at iteration 0.
    h : float
        The grid spacing: the stages' edge lengths are in voxels, :attr:`edge_length` in world units.
    """

    def __init__(self, stages, h: float):
        self.h = float(h)
        self.pending = list(stages)
        self.starts: list[dict] = []
        self.current: Stage = self.pending[0]
        self.enter(0)

    @property
    def beta(self) -> float:
        return self.current.beta

    @property
    def edge_length(self) -> float:
        """The current remeshing edge length, world units."""
        return self.current.edge_length * self.h

    def more(self) -> bool:
        """Whether a stage is still to come."""
        return bool(self.pending)

    def enter(self, iteration: int) -> None:
        """Enter the next stage at ``iteration``."""
        self.current = self.pending.pop(0)
        self.starts.append({"iteration": iteration, "beta": self.beta,
                            "edge_length_voxels": self.edge_length / self.h})
