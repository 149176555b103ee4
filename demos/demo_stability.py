# # Where the contact penalty fails: a stability map
#
# The paper's scheme takes the contact force from the previous step,
#
# $$ \frac{\eta^{n+1} - 2\eta^n + \eta^{n-1}}{\Delta t^2} + \dots = \frac{1}{\varepsilon}\chi\{\eta^n<0\}(v^n)^-, $$
#
# so at a node that hits the obstacle with speed $V$ the velocity becomes $v^{n+1} = (1 - r)v^n$ with
# $r = \Delta t/\varepsilon$. Theory: no overshoot for $r \le 1$, a spurious rebound with restitution
# $r - 1$ for $1 < r < 2$, and energy growth for $r \ge 2$. The semi-implicit penalty applies the same
# force to the *new* velocity, $v^{n+1} = v^n/(1 + r)$, and never rebounds.
#
# We test this on the flat landing: a string at height $h = 0.2$ with fixed ends, thrown down with
# $V = 1$; its flat middle lands at $t^* = h/V$ and, exactly, stays at rest (α = 0).

# +
import os
from pathlib import Path

from stringcontact.analysis import study

fast = os.environ.get("STRINGCONTACT_DEMO_FAST") == "1"
out = Path(os.environ.get("STRINGCONTACT_DEMO_OUT", "out/demo_stability"))
out.mkdir(parents=True, exist_ok=True)
# -

# ## One cell of the map
# `stability_case` runs the lumped scheme through `stringcontact.verification.reference.fd_solve` (the same scheme as
# `simulate`, without its refusal of $r \ge 2$), measures the restitution at the middle node and
# classifies the run.

for r in (0.8, 1.5, 4.0):
    row = study.stability_case("explicit", 1 / 100, r)
    print(f"explicit, r = {r}: {row['outcome']}, restitution {row['restitution']:.3f} (theory {row['restitution_theory']:.3f})")

# ## The whole map, the restitution curve and the sweep α → 0
# Every case is independent; under `mpirun -n K` the cases are dealt over the ranks.

rows = study.stability_map(quick=fast)
alpha_rows = study.alpha_sweep(quick=fast)
study.write_csv(out / "study_stability.csv", rows, study.STABILITY_COLUMNS)
study.write_csv(out / "study_alpha.csv", alpha_rows, study.ALPHA_COLUMNS)
print("wrote", study.plot_stability(rows, alpha_rows, out / "study_stability.png"))

# ## Schemes without ε: where they fail in Δt
# `projection` treats the elastic term explicitly, so it needs $\Delta t \le \Delta t_{max}$, which the
# solver computes from the operators: $2/\sqrt{\lambda_{max}(M^{-1}K)} = \Delta x$ on this mesh without
# viscosity, and $\alpha + \sqrt{\alpha^2 + \Delta x^2}$ with $C = \alpha K$. `newmark` (the trapezoidal
# rule) has no such limit.

steps = study.step_size_map(quick=fast)
study.write_csv(out / "study_step_size.csv", steps, study.STEP_COLUMNS)
print("wrote", study.plot_step_size(steps, out / "study_step_size.png"))
for row in steps:
    print(f"{row['scheme']:10s} alpha={row['alpha']:g} dt/dx={row['dt_over_dx']:.2f} (dt_max/dx="
          f"{row['dt_max_over_dx']:.2f}): {row['outcome']}")

# ## Reading it
# The explicit rows agree with the theory: inelastic up to $r = 1$, restitution $r - 1$ for
# $1 < r < 2$ (exactly $1$ at $r = 2$, the marginal case), energy growth above. The semi-implicit rows
# are inelastic everywhere, up to $r = 100$. The spring (the `elastic` variant) has a bound of its own, on
# $\Delta t^2/\varepsilon$ rather than $r$: that is why the bound belongs to the contact law
# (`Model.stability`). At α = 0 the energy the landing destroys is booked as *contact* dissipation, under
# every penalty and every ε: it is the energy the contact impulse takes out of the velocity it meets.
# `projection` fails just beyond its $\Delta t_{max}$ (and `simulate` refuses it there); viscosity moves
# that limit up. `newmark` runs at any $\Delta t$.
