"""The paper's method: shape-gradient descent of E(Γ) = ∫_Γ α φ² + β |∇_Γ φ|² dΓ (docs/METHOD.md).

Before the loop: the initial surface (by default, ``init='genus0'``, a genus-0 surface grown from the region
φ < 0 of the volume; the paper's Fibonacci sphere, radius 2, 1,896 vertices / 3,788 triangles, with
``init='sphere'``; or a user's closed genus-0 mesh, checked to lie in the grid), the noise estimate of the volume
and — on noisy volumes (``presmooth='auto'``) — Gaussian pre-smoothing of the grids ∇φ and D²φ are computed from
(φ itself is kept, so the data term has no shrinkage bias); there ``beta='auto'`` lowers β to 0.01 (∇φ of the
smoothed volume is wrong across voxel-thin parts) and the genus-0 start is grown from values smoothed only as
much as brings the noise below one voxel (``start_smooth='auto'``, :func:`start_smoothing`).

One iteration, every step vectorised over all vertices/faces (the only Python loops are over the
≤ 3 coordinates, the ≤ 30 halvings of a line search and the CG iterations):

1. **interpolation** – φ, ∇φ and D²φ at every vertex in one gather of the 8 corner rows of the volume's
   cached, stacked derivative grids (:class:`GridSampler`, the interpolation of
   :meth:`phantoms.Volume.sample`);
2. **curvature** – area-weighted vertex normals and the batched paraboloid fit (H; κ = 2H) over the
   1-ring (:meth:`geometry.operators.MeshOperators.curvature`);
3. **gradient** – the shape gradient at every vertex

       G = 2αφφ_n + 2β[(D²φ∇φ)·n − φ_n nᵀD²φ n] + κ[αφ² + β(|∇φ|² − φ_n²)] − 2β div_Γ(φ_n ∇_Γφ)

   (``gradient='full'``, the gradient of E) or without the last term (``gradient='paper'``, the paper's
   eq. (dJ_finel)).  The divergence term is the weak divergence (transpose of the P1 gradient) of the
   per-face field φ_n∇_Γφ sampled at the face centroids with the face normals — the samples the discrete
   energy uses, so that this term is the exact derivative of the discrete energy;
4. **preconditioner** – ``precondition='h1'``: the Sobolev velocity V = (M + sK)⁻¹ M G (M lumped areas,
   K cotangent stiffness) by Jacobi-preconditioned CG, warm-started; ``'none'``: V = G;
5. **step** – ``step='capped'``: the largest vertex move is capped at ``max_move`` voxels, then halved
   until the discrete energy E = Σ_f a_f g(centroid_f, n_f) decreases (Armijo) and no face normal turns
   by more than 60° (no fold); ``step='fixed'``: x ← x − τVn with the constant ``tau`` (the paper's
   printed loop, unguarded);
6. **relaxation** – tangential smoothing (toward the 1-ring centroid, within the tangent plane), added
   to the trial step (retried without it if the line search fails);
7. **energy** – E of the new mesh (from the accepted trial); stop when its relative change stays below
   ``tol`` or the largest normal move below ``move_tol`` voxels for 3 iterations.

After the last iteration, the post-steps (:mod:`.post`; geometric steps, not part of the descent): on clean
volumes (``polish='auto'``; ``'on'``/``'off'`` force it) the **crease polish** (:func:`crease_polish`) — edges
whose endpoints' ∇φ (at their Newton projections onto φ = 0) differ by more than ``polish_angle`` (45°) cross a
sharp crease; their endpoints are Newton-projected onto φ = 0 and one endpoint of each such edge is moved onto
the crease (the dual-contouring quadric of its 1-ring's tangent planes).  Why: the discrete energy prefers to
bridge a concave crease (near the kink the interpolated ∇φ blends both sides, so faces lying in the groove pay
β|∇_Γφ|²), which leaves a fused-spheres shape far off its crease without it.  Smooth surfaces have no crease
edges: the polish leaves them untouched.  Off on noisy volumes: there it finds spurious creases and roughens the
mesh.  Then the Newton projection onto φ = 0 (``projection``), the tip extension (``extend_tips``) and, on a
signed distance, the reach to the samples (``reach_samples``).  ``info['snapshots']`` are flow iterates (before
the post-steps), ``info['polish']`` records what the polish did (counts, the energy after it).

Stop reasons: ``converged``, ``max_iter``, ``line_search_floor`` (no decrease of E down to a 1e-4-voxel
move: the gradient no longer predicts a decrease of the discrete energy), ``diverged`` (non-finite
gradient, the mesh leaving the grid under ``step='fixed'``) — always with the iteration in
``info['stop_message']``; the returned mesh is the last finite one.
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
