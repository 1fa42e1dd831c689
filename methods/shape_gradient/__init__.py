"""The paper's method: shape-gradient descent of E(Γ) = ∫_Γ α φ² + β |∇_Γφ|² dΓ (docs/METHOD.md).

Before the loop (:mod:`.method`): the noise estimate, the initial surface (by default a genus-0 surface grown
from the region φ < 0, :mod:`.start`; the start choice, :mod:`.choose`, may try carved starts too), the
derivative grids of the (on noisy volumes pre-smoothed) volume, and the settings resolved once (:mod:`.settings`).

One iteration (:meth:`ShapeGradientFlow.step`), the paper's four steps, vectorised over all vertices:

1. **interpolate** – φ, ∇φ and D²φ at every vertex (:class:`GridSampler`), the normals and the paraboloid fit
   for H;
2. **gradient** – the shape gradient G at every vertex (:func:`shape_gradient`; ``gradient='paper'`` drops the
   divergence term as the paper prints it);
3. **precondition** – the Sobolev velocity V = (M + sK)⁻¹ M G (:mod:`.sobolev`), or V = G;
4. **step** – the largest move capped at ``max_move`` voxels, halved until the discrete energy decreases with
   no folded face (Armijo, :mod:`.linesearch`), plus the tangential relaxation; then the remesh and the stop
   tests (:mod:`.convergence`).

The named additions the flow calls: the carve limit (:mod:`.carve`), the L² fallback of the line search
(:mod:`.linesearch`), the stages (:mod:`.convergence`), the sign guard (:mod:`.signs`) and the intersection guard
(:mod:`.guard`).  After the last iteration
the post-steps (:mod:`.post`): the crease polish, the Newton projection, the tip extension (:mod:`.tips`) and
the reach to the samples (:mod:`.reach`).

Stop reasons (:data:`STOP_REASONS`): ``converged``, ``fixed_iterations``, ``max_iter``, ``line_search_floor``,
``diverged`` (a non-finite gradient), ``sign_guard`` — with the iteration in ``info['stop_message']``; the
returned mesh is the last finite one.
"""

from .energy import discrete_energy, evaluate_state, face_energies, gradient_from_state, shape_gradient
from .field import GridSampler, as_field, estimate_noise
from .flow import STOP_REASONS, ShapeGradientFlow
from .method import PRESETS, ShapeGradient
from .polish import crease_polish, newton_project
from .start import prepare_init_mesh

__all__ = ["ShapeGradient", "ShapeGradientFlow", "discrete_energy", "shape_gradient", "PRESETS",
           "STOP_REASONS", "prepare_init_mesh", "GridSampler", "as_field", "estimate_noise", "face_energies",
           "evaluate_state", "gradient_from_state", "crease_polish", "newton_project"]
