# # Three time schemes for one model
#
# The model is one UFL form, written in the unknown's time derivatives (`stringcontact.model.inelastic`):
#
# $$ \int \eta_{tt} w + \alpha \int \eta_{tx} w_x + \int \eta_x w_x = \int F w, \qquad
#    F = \tfrac{1}{\varepsilon}\chi\{\eta<0\}(\eta_t)^-. $$
#
# `stringcontact.fem.operators` takes it apart into the mass, damping and stiffness matrices $M, C, K$; a
# *time scheme* (`stringcontact.timestepping`) then marches them. The driver, `simulate`, knows none of them:
#
# * `paper`, the paper's Section 6: implicit Euler in the elastic and viscous terms, the penalty from the
#   previous step. Its implicit elastic term damps; the contact needs $r = \Delta t/\varepsilon \le 1$.
# * `projection`: central differences (explicit elastic term, lumped mass), implicit viscosity, and after
#   each step every node below the obstacle is put back on it. Restitution 0 with no $\varepsilon$ at all:
#   the paper's condition (A4), $\eta_t = 0$ on contact, holds exactly. Its step is limited by
#   $\Delta t_{max}$, computed from $M$, $K$ and $C$.
# * `newmark`: the trapezoidal rule, energy-conserving, unconditionally stable, with the semi-implicit
#   penalty (a damping on the new velocity) on the active set, $\varepsilon \to 0$ allowed.

# +
import os
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

import stringcontact as sc
from stringcontact.analysis import study

fast = os.environ.get("STRINGCONTACT_DEMO_FAST") == "1"
out = Path(os.environ.get("STRINGCONTACT_DEMO_OUT", "out/demo_schemes"))
out.mkdir(parents=True, exist_ok=True)
print("schemes:", *(f"\n  {name}: {text}" for name, text in sc.SCHEMES.items()))
# -

# ## Example 1, three ways
# The same scene, the same model; only `scheme=` changes. Each scheme reports the terms of its own
# discrete energy identity, so the balance $E(0) = E(T) + D_{visc} + D_{con} + D_{num}$ closes to
# round-off for all three. What differs is *where* the energy goes.

n = 1000 if fast else 5000
scene = study.example1_scene(n)
runs = {}
for name, options in (("paper", {}), ("projection", {}), ("newmark", {"penalty": "semi-implicit"})):
    t0 = time.perf_counter()
    runs[name] = sc.simulate(scene if name != "paper" or not fast else scene.replace(eps=scene.dt),
                             scheme=name, comm=MPI.COMM_SELF, **options)
    res, wall = runs[name], time.perf_counter() - t0
    e, E0 = res.energy, res.total_energy[0]
    print(f"{name:10s} {wall:5.2f} s  numerical {e['numerical_dissipation'][-1] / E0:6.2%}  "
          f"contact {e['contact_dissipation'][-1] / E0:6.2%}  viscous {e['viscous_dissipation'][-1] / E0:6.2%}  "
          f"min eta {res.min_eta:+.4f}  residual {np.max(np.abs(res.balance_residual)) / E0:.1e}")

# `projection` never goes below the obstacle (min η = 0) and has no numerical dissipation: the leapfrog
# conserves its own energy, so everything the string loses is viscous or contact. The penalty schemes
# penetrate by about $\varepsilon|v_0|$ (`paper`) or one step's travel (`newmark`, $\varepsilon \to 0$).

# ## The contact set
# The fraction of the string on the obstacle at a few times:

for t in (0.04, 0.1, 0.2):
    row = int(np.argmin(np.abs(runs["paper"].t - t)))
    print(f"t = {runs['paper'].t[row]:.3f}: " + ", ".join(
        f"{name} {res.contact[int(np.argmin(np.abs(res.t - t)))].mean():.3f}" for name, res in runs.items()))

# ## Accuracy per cost on the exact flat landing
# $\alpha = 0$, $\Delta t = \Delta x$: the landing is exact, so the error is measured, not estimated.

sizes = (125, 250, 500) if fast else (250, 500, 1000, 2000)
for name in ("projection", "semi-implicit", "newmark"):
    errs = []
    for size in sizes:
        run = study.run_method(study.flat_landing_scene(size), study.METHODS[name], rows=round(0.6 * min(sizes)))
        errs.append(study.errors_against_exact(run, study.flat_landing_exact)["err_eta"])
    order = study.fitted_order([1 / s for s in sizes], errs)
    print(f"{name:14s} eta error " + "  ".join(f"{s}: {e:.2e}" for s, e in zip(sizes, errs)) + f"   order {order:.2f}")

# `projection` converges at about first order and is the most accurate at every grid; the penalty
# schemes stop at order 1/2, limited by the one step of penetration their active set needs. The
# work-precision chart of `stringcontact study work-precision` puts the costs beside these errors
# (docs/explanation/study.md).

(out / "schemes.txt").write_text("\n".join(f"{k}: {v.scheme} {v.status}" for k, v in runs.items()) + "\n")
