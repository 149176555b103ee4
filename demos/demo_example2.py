# # Example 2 of the paper: a contact set in several pieces
#
# This demo reproduces Example 2 of Section 6 of B. Muha and S. Trifunović,
# *Analysis of an Inelastic Contact Problem for the Damped Wave Equation*: a
# non-oscillatory, discontinuous string, thrown down fast on its left part and slowly on its right
# part. The paper's point: the contact set need not be an interval; it can consist of several
# disconnected components. We run the paper's resolution, write the solution for ParaView, draw the
# paper's missing figures and count the components.
#
# ## The model and the scheme
#
# As in Example 1: the string's height $\eta(t, x)$ on $(0, l)$ obeys
#
# $$
# \eta_{tt} - \alpha\,\eta_{txx} - \eta_{xx} = \frac{1}{\varepsilon}\,\chi_{\{\eta < 0\}}\,(\eta_t)^-,
# $$
#
# discretised with P1 elements, lumped mass, implicit elasticity and viscosity and the contact force
# from the previous step:
#
# $$
# M\,\frac{\eta^{n+1} - 2\eta^n + \eta^{n-1}}{\Delta t^2} + \alpha K\,\frac{\eta^{n+1} - \eta^n}{\Delta t}
# + K \eta^{n+1} = M F(\eta^n, v^n).
# $$
#
# The data, as printed: $l = 1$, $T = 0.5$, $\Delta t = \Delta x = 1/5000$, $\alpha = 0.01$,
# $\varepsilon = 0.0005$,
#
# $$
# \eta^0 = \begin{cases} x & 0 \le x < 0.2\\ \sin(\pi(x - 0.2)/0.3) & 0.2 \le x < 0.8\\ 2 - x & 0.8 \le x \le 1
# \end{cases}, \qquad
# v^0 = \begin{cases} -50 & x < 0.6\\ -0.5 & x \ge 0.6 \end{cases}.
# $$
#
# $\eta^0$ jumps at $x = 0.2$ and $x = 0.8$ and is negative on $(0.5, 0.8)$: the string starts below
# the obstacle there, and the loader warns. The ends are held at $\eta^0$'s end values, 0 and 1
# (`stringcontact show example2` lists every reading of the printed data).

# +
import os
import warnings
from pathlib import Path

import numpy as np

import stringcontact as sc
from stringcontact.plot import run_pictures

FAST = os.environ.get("STRINGCONTACT_DEMO_FAST") == "1"  # reduced resolution for the test suite
OUT = Path(os.environ.get("STRINGCONTACT_DEMO_OUT", "out/demo_example2"))
# -

# ## Run at the paper's resolution

with warnings.catch_warnings():
    warnings.simplefilter("ignore", sc.SceneWarning)  # eta0 < 0 on (0.5, 0.8): as printed, on purpose
    scene = sc.load_scene("example2")
    if FAST:
        scene = scene.replace(nx=400, nt=1250)
run_dir = OUT / scene.name
res = sc.simulate(scene, output=sc.Output(run_dir, force=True, progress=not FAST))
l = scene.length
print(f"{scene.name}: nx = {scene.nx}, dt = {scene.dt:g}, {len(res.t)} stored rows, written to {run_dir}")

# ## The pictures
#
# `snapshots.png` is the paper's Figure 3 (t = 0, 0.04, 0.08, 0.16, 0.28, 0.32), `contact_set.png`
# and `velocity_field.png` its Figure 4, `energy.png` the energy balance.

pictures = run_pictures.show_pictures(run_dir)

# ## What the paper observes, measured
#
# **The contact set splits into several disconnected components.** A component is a maximal run of
# at least two neighbouring nodes with $\eta \le 0$ (`run_pictures.contact_components`). Single nodes are
# left out: the left end is held at $\eta = 0$ and so always touches the obstacle at one point.

components = [run_pictures.contact_components(res.x, row) for row in res.contact]
count = np.array([len(c) for c in components])
i_most = int(np.argmax(count))
several = count >= 2
print(f"most components at one time: {count[i_most]}, at t = {res.t[i_most]:.4f}: "
      + ", ".join(f"[{a:.3f}, {b:.3f}]" for a, b in components[i_most]))
if several.any():
    print(f"two or more components in {several.sum()} of {len(res.t)} stored rows, "
          f"between t = {res.t[several].min():.4f} and t = {res.t[several].max():.4f}")
for i in run_pictures.snapshot_rows(res):
    span = ", ".join(f"[{a:.3f}, {b:.3f}]" for a, b in components[i]) or "none"
    print(f"  t = {res.t[i]:.2f}: {count[i]} component(s): {span}")

# The contact set first has a piece where the string starts below the obstacle, $(0.5, 0.8)$, and
# pieces where the fast left part lands; these merge, and the ends pull the string off later.

fraction = res.contact_length / l
i_max = int(np.argmax(fraction))
with_parts = count > 0
t_last = float(res.t[with_parts].max()) if with_parts.any() else float("nan")
print(f"largest contact fraction {fraction[i_max]:.3f} at t = {res.t[i_max]:.4f}; "
      f"last component seen at t = {t_last:.4f} (T = {scene.T})")

# **The velocity vanishes on contact.** The left part lands at speed 50; on the contact set the
# speed is a small fraction of that.

impact_speed = float(np.max(np.abs(scene.initial_velocity(res.x))))
speed_on = np.abs(res.velocity[res.contact])
print(
    f"|v| on the contact set: median {np.median(speed_on):.3g}, 90th percentile {np.percentile(speed_on, 90):.3g} "
    f"(impact speed {impact_speed:g}; median off contact {np.median(np.abs(res.velocity[~res.contact])):.3g})"
)

# **Energy is lost only through viscosity and contact** (plus the scheme's own numerical
# dissipation), and the balance closes to round-off. Here viscosity dominates: the discontinuous
# $\eta^0$ has large gradients, and $\alpha\int\eta_{tx}^2$ damps them quickly.

e = res.energy
E = res.total_energy
print(
    f"E(0) = {E[0]:.6g} = E(T) {E[-1]:.6g} + viscous {e['viscous_dissipation'][-1]:.6g} "
    f"+ contact {e['contact_dissipation'][-1]:.6g} + numerical {e['numerical_dissipation'][-1]:.6g}"
)
print(f"largest |balance residual| {np.max(np.abs(res.balance_residual)):.2e} (relative {np.max(np.abs(res.balance_residual)) / E[0]:.1e})")

# ## Open the result in ParaView
#
# Open `OUT/example2/solution.xdmf` with the **Xdmf3ReaderT** reader, *Warp By Scalar* with `eta`,
# colour by `contact`, and step through time: the red pieces appear, merge and vanish.
