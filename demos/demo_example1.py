# # Example 1 of the paper: an oscillating string thrown onto the obstacle
#
# This demo reproduces Example 1 of Section 6 of B. Muha and S. Trifunović,
# *Analysis of an Inelastic Contact Problem for the Damped Wave Equation*: a string with
# symmetric, oscillatory initial shape is thrown down onto a rigid obstacle at speed 50. It runs the
# paper's resolution, writes the solution for ParaView (`solution.xdmf`), draws the paper's missing
# figures (snapshots, contact set, velocity field) and the energy balance, and measures what the paper
# says about the run.
#
# ## The model
#
# The string's height $\eta(t, x)$ over $(0, l)$, with its ends held at height $h$, obeys the damped
# wave equation with a one-sided contact force:
#
# $$
# \eta_{tt} - \alpha\,\eta_{txx} - \eta_{xx} = F, \qquad
# F = \frac{1}{\varepsilon}\,\chi_{\{\eta < 0\}}\,(\eta_t)^-,
# $$
#
# where $(s)^- = \max(-s, 0)$. The force acts only below the obstacle $y = 0$ and only against a
# downward velocity: it brakes the string, it never pushes it back up. So contact is *inelastic*:
# the velocity vanishes where the string lies on the obstacle, and, with $E = \frac12\int \eta_t^2 +
# \frac12\int \eta_x^2$, the energy balance (1.4) reads
#
# $$
# E(t) + \alpha \int_0^t\!\!\int \eta_{tx}^2 + \int_0^t\!\!\int (-F)\,\eta_t = E(0):
# $$
#
# energy leaves only through viscosity and contact.
#
# ## The scheme
#
# P1 finite elements with a lumped mass matrix $M$ and stiffness $K$ (on a uniform mesh this is the
# paper's finite-difference scheme), elastic and viscous terms implicit, the contact force explicit:
#
# $$
# M\,\frac{\eta^{n+1} - 2\eta^n + \eta^{n-1}}{\Delta t^2} + \alpha K\,\frac{\eta^{n+1} - \eta^n}{\Delta t}
# + K \eta^{n+1} = M F(\eta^n, v^n), \qquad v^n = \frac{\eta^n - \eta^{n-1}}{\Delta t}.
# $$
#
# The data are the paper's: $l = 1$, $T = 0.3$, $\Delta t = \Delta x = 1/5000$, $\alpha = 0.01$,
# $\varepsilon = 0.0005$, $\eta^0 = 1 + \frac12 \sin^2(10\pi x)$, $v^0 = -50$, ends held at
# $h = 1$ (`stringcontact show example1` lists how the printed data were read).

# +
import os
from pathlib import Path

import numpy as np

import stringcontact as sc
from stringcontact.plot import run_pictures

FAST = os.environ.get("STRINGCONTACT_DEMO_FAST") == "1"  # reduced resolution for the test suite
OUT = Path(os.environ.get("STRINGCONTACT_DEMO_OUT", "out/demo_example1"))
# -

# ## Run at the paper's resolution
#
# 5000 cells and 1500 steps take a few seconds. The run stores about 400 time levels; it writes
# `solution.xdmf`/`.h5` (the fields `eta`, `velocity`, `contact`, `contact_force` at about 100 of
# them, `max_frames`), `diagnostics.csv` (all of them), `summary.json` and the five pictures into
# `OUT/example1`.

scene = sc.load_scene("example1")
if FAST:
    scene = scene.replace(nx=400, nt=750)
run_dir = OUT / scene.name
res = sc.simulate(scene, output=sc.Output(run_dir, force=True, progress=not FAST))
l = scene.length
print(f"{scene.name}: nx = {scene.nx}, dt = {scene.dt:g}, {len(res.t)} stored rows, written to {run_dir}")

# ## The pictures
#
# `snapshots.png` is the paper's Figure 1 (η at t = 0, 0.02, 0.04, 0.06, 0.2, 0.3, contact in red),
# `contact_set.png` and `velocity_field.png` are its Figure 2, and `energy.png` shows the balance.
# In a notebook they are displayed here; as a script the paths are printed.

pictures = run_pictures.show_pictures(run_dir)

# ## What the paper observes, measured
#
# **Contact forms and spreads over almost the whole string.** The contact set is
# $\{\eta \le 0\}$; its measure divided by $l$ is the fraction of the string in contact.

fraction = res.contact_length / l
i_max = int(np.argmax(fraction))
print(f"largest contact fraction {fraction[i_max]:.3f} of the string, at t = {res.t[i_max]:.4f}")
for i in run_pictures.snapshot_rows(res):
    parts = run_pictures.contact_components(res.x, res.contact[i])
    span = ", ".join(f"[{a:.3f}, {b:.3f}]" for a, b in parts) or "none"
    print(f"  t = {res.t[i]:.2f}: contact fraction {fraction[i]:.3f}, contact set {span}")

# **The contact set stays symmetric.** The data are symmetric about $x = l/2$; on the uniform mesh
# the mirror image of node $i$ is node $N - i$, so we compare each stored row with its reverse.

mirror_mismatch = np.max(np.mean(res.contact != res.contact[:, ::-1], axis=1))
eta_asymmetry = np.max(np.abs(res.eta - res.eta[:, ::-1]))
print(f"largest fraction of nodes whose contact state differs from the mirror node: {mirror_mismatch:.3g}")
print(f"largest |eta(x) - eta(l - x)|: {eta_asymmetry:.3g}")

# **Later, the ends pull the string back and the contact set shrinks.** The ends are held at
# $h = 1$; the tension they exert peels the string off the obstacle from both sides.

after_peak = res.t >= res.t[i_max]
in_contact = fraction > 0
t_last = float(res.t[in_contact].max()) if in_contact.any() else float("nan")
for t_probe in (0.06, 0.1, 0.2, 0.25):
    i = int(np.argmin(np.abs(res.t - t_probe)))
    print(f"  contact fraction at t = {res.t[i]:.3f}: {fraction[i]:.3f}")
shrinking = bool(np.all(np.diff(fraction[after_peak]) <= 1e-12))
print(f"contact fraction never grows after its peak: {shrinking}; last contact at t = {t_last:.4f} (T = {scene.T})")

# **The velocity vanishes on contact.** The string hits the obstacle at speed 50; where it lies on
# the obstacle, the penalty has braked it to (almost) rest. We compare $|\eta_t|$ on the contact set
# with the impact speed, over all stored rows.

impact_speed = float(np.max(np.abs(scene.initial_velocity(res.x))))
speed_on = np.abs(res.velocity[res.contact])
speed_off = np.abs(res.velocity[~res.contact])
print(
    f"|v| on the contact set: median {np.median(speed_on):.3g}, 99th percentile {np.percentile(speed_on, 99):.3g} "
    f"(impact speed {impact_speed:g}; median off contact {np.median(speed_off):.3g})"
)

# **Energy is lost only through viscosity and contact.** The discrete balance closes to round-off.
# Contact dissipation is the work of the contact force with each step's mean velocity, so the landing,
# where $v$ jumps by 50 within a few steps, is booked as contact; what the implicit Euler scheme damps
# besides is its numerical dissipation, small here. Contact dissipation grows only while part of the
# string is in contact.

e = res.energy
E = res.total_energy
gained_without_contact = np.diff(e["contact_dissipation"])[(fraction[1:] == 0) & (fraction[:-1] == 0)].sum()
print(
    f"E(0) = {E[0]:.6g} = E(T) {E[-1]:.6g} + viscous {e['viscous_dissipation'][-1]:.6g} "
    f"+ contact {e['contact_dissipation'][-1]:.6g} + numerical {e['numerical_dissipation'][-1]:.6g}"
)
print(f"largest |balance residual| {np.max(np.abs(res.balance_residual)):.2e} (relative {np.max(np.abs(res.balance_residual)) / E[0]:.1e})")
print(f"contact dissipation gained between stored rows without contact: {gained_without_contact:.3g}")

# ## Open the result in ParaView
#
# Open `OUT/example1/solution.xdmf` with the **Xdmf3ReaderT** reader, apply *Warp By Scalar* with
# `eta` (normal 0, 1, 0) and colour by `contact`; the time slider steps through the XDMF frames.
# `stringcontact plot OUT/example1` redraws the five pictures from the saved files alone.
