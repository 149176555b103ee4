# ---
# jupytext:
#   text_representation:
#     extension: .py
#     format_name: light
# ---

# # The paper's theorems on computed solutions
#
# The paper proves, for the limit of the penalised problem, that the contact force F and the contact
# dissipation D
#
# - are non-negative (A1),
# - live on the free boundary ∂{η = 0}, a set of measure zero (A2),
# - vanish where the string moves up (A3),
# - stop the string: the velocity vanishes right after contact (A4, Theorem 2.2),
# - equal the jump of the stress −[η_x + α η_tx] across a moving contact boundary (Theorem 2.3(1), (2.10)),
#   and the velocity jump where a whole segment lands at once (Theorem 2.3(2), (2.12)),
#
# and that the energy balance (1.4) holds. A computed solution is penalised (ε > 0) and discrete, so each
# statement becomes a number with an expected limit under refinement. `stringcontact.analysis.theorems` measures them;
# `stringcontact check SCENE` prints the same table.

# +
import os
import warnings
from pathlib import Path

import stringcontact as sc
from stringcontact.analysis import theorems as th

FAST = os.environ.get("STRINGCONTACT_DEMO_FAST") == "1"
OUT = Path(os.environ.get("STRINGCONTACT_DEMO_OUT", "out/demo_theorems"))
OUT.mkdir(parents=True, exist_ok=True)
warnings.simplefilter("ignore", sc.SceneWarning)
# -

# ## Refinement with ε tied to the grid
#
# The theorems are statements about ε, Δx, Δt → 0. `th.refine` halves all three per level, keeping
# Δt/Δx and r = Δt/ε fixed (r = 0.4 in the paper's data), and stores every time step, which the checks
# need: row n holds the force F^n applied in the step t_{n−1} → t_n and the velocity v^n of that step.
# `th.run_checks` does this refinement (and, for the energy, a refinement of Δt alone) and runs every check
# below on it, as `stringcontact check` does.

scene = sc.load_scene("example1")
scene = th.coarsened(scene, 10 if FAST else 2)
levels = 2 if FAST else 3
checks, finest, results = th.run_checks(scene, levels=levels, time_levels=levels)
[(r.scene.nx, r.scene.nt, r.scene.eps) for r in results]

# ## The table
#
# Each check returns a `Check`: the measured value on the finest level, the expectation, a verdict, and the
# trend over the levels. "holds in the limit" means the measured value falls at every refinement;
# "holds by construction" means the scheme cannot violate it; "fails" is reported as such.

print(th.format_table(checks))
print(th.format_trends(checks))

# ## Why (2.10) does not close here
#
# The discrete momentum equation, summed over a band [a, b] around a front, is exactly
#
# $$ \sum_j m_j F^n_j \Delta t = -(S_{b+1/2} - S_{a-1/2})\Delta t + \sum_j m_j (v^n_j - v^{n-1}_j), $$
#
# impulse = stress jump + inertia, with S = η_x + α η_tx. Formula (2.10) says the inertia vanishes in the
# limit, which needs η_t continuous across the front (η ∈ H¹(H¹)). In Example 1 the string lands at
# |v| ≈ 47 and the fronts run faster than the wave speed, so each front sweeps a velocity jump along and the
# inertia term, not the stress jump, carries the force:

sj = th.stress_jump_balance(finest, width=round(0.02 / finest.scene.dx))
{k: sj[k] for k in ("band_impulse", "stress_jump_impulse", "inertia", "identity_closure")}

# ## The paper's Figure 1
#
# The contact set {η ≤ 0} in the (x, t) plane, its free boundary, and the force density on it. On the right,
# the force on the fronts per unit time against the stress jump across them.

th.draw_figure1(finest, OUT / "figure1_example1.png")

# The exact α = 0 case: a flat string at height h = 0.2 thrown down at V = 1 lands at once at t* = 0.2,
# and Theorem 2.3(2) predicts the landing impulse per unit length V.

flat = th.flat_landing_scene(200, 240, r=0.4) if FAST else th.flat_landing_scene(500, 600, r=0.4)
flat_results = th.refine(flat, levels=2)
landing = th.check_landing(flat_results, V=1.0)
print(th.format_table([landing]))
print(landing.detail)
th.draw_figure1(flat_results[-1], OUT / "figure1_flat_landing.png")
print(f"wrote {OUT}")
