# # Convergence: in $\Delta t = \Delta x$ and in $\varepsilon$
#
# The flat landing has an exact solution for α = 0 (`stringcontact.verification.exact.flat_landing`): the string's
# flat middle lands at $t^* = h/V$ and stops; the ends then lift it off with waves of slope $V/2$. The
# velocity jumps, so no scheme converges at its formal order. We measure the observed orders of the
# $L^\infty(0,T;L^2)$ error of $\eta$, the $L^2$ error of the velocity at $T$ and the contact-set error
# under $\Delta t = \Delta x \to 0$, and of the penetration $-\min\eta$ and the error under
# $\varepsilon \to 0$ on a fixed grid.

# +
import os
from pathlib import Path

from stringcontact.analysis import study

fast = os.environ.get("STRINGCONTACT_DEMO_FAST") == "1"
out = Path(os.environ.get("STRINGCONTACT_DEMO_OUT", "out/demo_convergence"))
out.mkdir(parents=True, exist_ok=True)
# -

# ## Run the sweeps
# `convergence` returns every run and the fitted orders (least squares in log-log).

result = study.convergence(quick=fast)
for o in result["orders"]:
    print(f"{o['sweep']:3s} {o['method']:14s} {o['quantity']:12s} order {o['order']:.2f}")

# ## The `--tol` estimate against the true error
# `stringcontact run SCENE --tol X` refines until a two-resolution Richardson estimate
# $\|\eta_{2n} - \eta_n\|/(2^p - 1)$ is below X. On the exact case we can check it.

tracking = study.tolerance_tracking((3e-2,) if fast else (3e-2, 1e-2))
for t in tracking:
    print(f"tol {t['tol']:g}: {t['method']} at nx={t['nx']}: estimate {t['estimate']:.3g}, true {t['true_error']:.3g}")

study.write_csv(out / "study_convergence.csv", result["runs"], study.CONVERGENCE_COLUMNS)
study.write_csv(out / "study_orders.csv", result["orders"], study.ORDER_COLUMNS)
study.write_csv(out / "study_tolerance.csv", tracking, study.TOLERANCE_COLUMNS)
print("wrote", study.plot_convergence(result, out / "study_convergence.png"))

# ## Reading it
# The error of η converges with order about 1/2 for all three methods: the velocity jump at landing and
# the smearing of the lift-off fronts by the implicit elastic term, not the penalty, limit the order.
# The penetration is first order in ε (it is ε·V) until ε reaches Δt; below that it stays at Δt·V.
