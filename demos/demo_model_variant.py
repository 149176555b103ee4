# ---
# jupytext:
#   text_representation:
#     extension: .py
#     format_name: light
# ---

# # Writing a model variant: a soft, damped ground
#
# The paper's obstacle is rigid and its contact is perfectly inelastic: the velocity penalty
#
# $$F = \frac{1}{\varepsilon}\,\chi_{\{\eta<0\}}\,(\eta_t)^-$$
#
# only brakes a string that moves down below $y = 0$, so a landing segment stops dead. Suppose the
# ground is instead a soft, damped bed (a Kelvin–Voigt foundation: a spring of stiffness $k$ and a
# dashpot $c$ per unit length). Below the ground it pushes back with
#
# $$F = \bigl(k\,\eta^- - c\,\eta_t\bigr)^+ \quad\text{where } \eta < 0,$$
#
# the outer $(\cdot)^+$ because a ground can push but not pull. A string point that hits it at speed $V$
# bounces off with the restitution coefficient $e = \exp\bigl(-\zeta\pi/\sqrt{1-\zeta^2}\bigr)$,
# $\zeta = c/(2\sqrt{k})$, instead of $e = 0$.
#
# This demo writes that variant as a user would: one UFL function for the force (and one for its stored
# energy) in a small package of its own, `examples/soft_ground`, that registers the model under a name.
# The time loop, the solver, the output and the pictures stay as they are.

# +
import inspect
import os
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import stringcontact as sc

FAST = os.environ.get("STRINGCONTACT_DEMO_FAST") == "1"
OUT = Path(os.environ.get("STRINGCONTACT_DEMO_OUT", "out/demo_model_variant"))
OUT.mkdir(parents=True, exist_ok=True)
# -

# ## What a model is
#
# A `stringcontact.Model` is a handful of plain functions that return UFL (see `docs/howto/models.md`):
#
# - `momentum_form(eta, eta_t, eta_tt, force, w, p)`: the semi-discrete weak form, linear in the four
#   placeholders. The time scheme takes it apart with `ufl.derivative` into mass, damping and stiffness
#   matrices, assembled and factorised once.
# - `penalty(eta, v, p)`: the contact force density, a pointwise expression in the previous step's
#   $\eta^n$ and $v^n$. It may be nonlinear; it is evaluated at the nodes and applied explicitly.
# - `contact_set(eta, p)`: the indicator written to the results.
# - `contact_energy(eta, p)` (optional): the energy a conservative part of the law stores, so that the
#   solver's energy guard does not mistake the spring giving its energy back for an instability.
#
# Our ground changes only `penalty` (and adds `contact_energy`). We choose a bed that a string point
# hitting it at speed $V = 50$ indents by $\delta = 0.1$ (an undamped spring stops it after
# $V/\sqrt{k}$), so $k = (V/\delta)^2$, and the dashpot for a restitution of one half. Its constants
# $k$ and $c$ are the model's declared constants (`ModelConstant`): a scene changes them in its
# `[parameters]` table, and the UFL reads them as `p.constants["k"]`.
#
# ## A model is a package: `examples/soft_ground`
#
# The whole variant is one module, `soft_ground.py`, beside a `pyproject.toml` that registers it under
# the entry-point group `stringcontact.models`:
#
# ```toml
# [project.entry-points."stringcontact.models"]
# soft_ground = "soft_ground:soft_ground"
# ```
#
# Installed with `pip install -e examples/soft_ground` (`scripts/setup` does it), it is a model like the
# built-in ones: a scene file says `model = "soft_ground"` (a scene only ever *names* a registered model:
# nothing in it is imported or run), the command line `--model soft_ground`, Python
# `sc.load_model("soft_ground")`; `stringcontact models` lists it. Copy the folder to start your own.
# Here is the module, loaded through its registered name:

soft_ground = sc.load_model("soft_ground")
print(inspect.getsource(inspect.getmodule(soft_ground.penalty)))

# `dataclasses.replace(sc.inelastic, ...)` keeps the rest of the paper's model (the viscoelastic string,
# the contact indicator $\eta \le 0$).

# ## The same scene, both models
#
# The paper's Example 1: an oscillating string thrown down at speed 50, at the paper's time step
# ($r = \Delta t/\varepsilon = 0.4$). With `STRINGCONTACT_DEMO_FAST=1` it runs on a ten times coarser grid.
# (Keep $\Delta t$: with $r = 0.8$ the paper's scheme lets the landed middle lift off much earlier,
# at $t \approx 0.11$.) The ground's force is explicit too, so its time scale must be resolved:
# $\Delta t\sqrt{k} = 0.1$ and $c\,\Delta t = 0.04$.

scene = sc.load_scene("example1")
if FAST:
    scene = scene.replace(nx=500)
results = {}
for model in (sc.inelastic, soft_ground):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sc.SceneWarning)
        results[model.name] = sc.simulate(scene, model=model)
paper, ground = results["inelastic"], results["soft_ground"]

# Both runs keep their energy books: $E(0) + W = E(t) + D_\mathrm{visc} + D_\mathrm{con} + D_\mathrm{num}$
# closes to round-off for each, so the two can be compared term by term.

for name, res in results.items():
    e = res.energy
    print(
        f"{name:12s} E(0) = {res.total_energy[0]:8.2f}  E(T) = {res.total_energy[-1]:7.2f}  "
        f"contact {e['contact_dissipation'][-1]:7.2f}  viscous {e['viscous_dissipation'][-1]:7.2f}  "
        f"min eta = {res.min_eta:.4f}  balance residual {abs(res.balance_residual[-1]):.1e}"
    )
    assert abs(res.balance_residual[-1]) < 1e-8 * res.total_energy[0]

# The soft ground gives part of the energy back: the string leaves the ground sooner and higher. It also
# sinks deeper: less than $\delta = 0.1$ (the dashpot helps), against the rigid penalty's $\varepsilon V$.

# ## The two contact sets side by side
#
# Each picture is the contact set $\{\eta \le 0\}$ in the $(x, t)$ plane. On the paper's rigid, inelastic
# obstacle the contact set spreads from the five troughs, merges, and then peels off from the ends; the
# middle leaves last (at t ≈ 0.29 at the paper's resolution, earlier on a coarse grid). On the soft
# ground the string touches down along its whole length at once, bounces off after a few milliseconds
# and is still in the air at T = 0.3.

# +
fig, axes = plt.subplots(1, 2, figsize=(10, 4.2), sharey=True, constrained_layout=True)
for ax, (title, res) in zip(axes, [("paper: rigid, inelastic", paper), ("soft ground, restitution 0.5", ground)]):
    ax.pcolormesh(res.x, res.t, res.contact.astype(float), cmap="Greys", vmin=0, vmax=1.6, shading="nearest")
    ax.set_title(f"{title}\ncontact {np.mean(res.contact):.0%} of the (x, t) plane")
    ax.set_xlabel("x")
axes[0].set_ylabel("t")
fig.suptitle(f"Contact set {{η ≤ 0}}, example1, nx = {scene.nx}, nt = {scene.nt}, ε = {scene.eps:g}")
picture = OUT / "contact_sets.png"
fig.savefig(picture, dpi=120)
plt.close(fig)
print(f"wrote {picture}")
# -

# ## Energy
#
# The kinetic plus elastic energy of the two runs: the paper's contact destroys the impact energy; the
# soft ground returns part of it. For a point mass on this bed the returned fraction would be
# $e^2 = 0.25$; the string keeps a little more, because the bed cannot pull (the outer $(\cdot)^+$ cuts
# the dashpot off before it would pull the string back down).

# +
touching = np.flatnonzero(ground.contact.any(axis=1))
before, after = ground.total_energy[touching[0] - 1], ground.total_energy[touching[-1] + 1]
print(f"soft ground: energy {before:.1f} before the impact, {after:.1f} after: {after / before:.2f} returned")

fig, ax = plt.subplots(figsize=(6, 3.6), constrained_layout=True)
for label, res in [("paper", paper), ("soft ground", ground)]:
    ax.plot(res.t, res.total_energy, label=label)
ax.set_xlabel("t")
ax.set_ylabel("kinetic + elastic energy")
ax.legend()
energy_picture = OUT / "energy.png"
fig.savefig(energy_picture, dpi=120)
plt.close(fig)
print(f"wrote {energy_picture}")
# -

# ## A nonlinear variant: a cubic foundation
#
# The penalty is explicit and pointwise. A term of the momentum equation itself may be nonlinear too: a
# string on a nonlinear elastic bed, ∫ (k η + k₃ η³) w, is one more line of UFL. A form that is not linear
# in η (or η_t) makes every time step a Newton solve (PETSc SNES, with line search; the Jacobian is
# `ufl.derivative` of the form), and the ledger books the model's own stored energy,
# ∫ ½η_x² + ½kη² + ¼k₃η⁴, given as `stored_energy`:

# +
import dataclasses

import ufl

K, K3 = 1.0, 1.0


def foundation_form(eta, eta_t, eta_tt, force, w, p):
    return sc.inelastic.momentum_form(eta, eta_t, eta_tt, force, w, p) + (K * eta + K3 * eta**3) * w * ufl.dx


def foundation_energy(eta, p):
    return 0.5 * ufl.inner(ufl.grad(eta), ufl.grad(eta)) + 0.5 * K * eta**2 + 0.25 * K3 * eta**4


cubic = dataclasses.replace(sc.inelastic, name="cubic", momentum_form=foundation_form, stored_energy=foundation_energy)
with warnings.catch_warnings():
    warnings.simplefilter("ignore", sc.SceneWarning)
    res = sc.simulate(scene, model=cubic)
print(f"cubic: {res.counters['newton iterations']} Newton iterations in {scene.nt} steps "
      f"({res.solver['nonlinear solver']}); E(0) = {res.total_energy[0]:.2f} "
      f"(the paper's model: {paper.total_energy[0]:.2f}); balance residual {abs(res.balance_residual[-1]):.1e}")
assert abs(res.balance_residual[-1]) < 1e-8 * res.total_energy[0]
# -

# The same model ships registered as `cubic_foundation` (`stringcontact run example1 --model
# cubic_foundation`), beside `large_deflection`, the geometrically exact string whose tension term is
# η_x/√(1 + η_x²); `docs/howto/nonlinear_models.md` shows how to write such variants, one with several
# fields among them.

# ## A moving obstacle: a piston throws the string
#
# The obstacle may move: the scene's `obstacle` is an expression in $x$ and $t$, $\psi(x, t)$, read by
# `loaded_obstacle`. The built-in scene `piston` holds a string at rest at height 0 (its ends held there)
# on the top of a piston under its middle, $|x - \tfrac12| < 0.2$, which rises at speed 2 and stops at
# height 0.3 at $t = 0.15$:
#
# $$\psi(x, t) = 0.3\,\min(t/0.15,\ 1)\ \text{ on } |x - \tfrac12| < 0.2, \qquad -1 \text{ elsewhere}.$$
#
# Scheme `projection` puts $\psi(\cdot, t^{n+1})$ into each step's constraint $\eta^{n+1} \ge \psi^{n+1}$:
# while the piston rises the string lies on it and moves with it; when the piston stops the string keeps
# going up (it is thrown), flies, is pulled back by its tension and lands on the piston, inelastically.
# (The explicit velocity penalty of scheme `paper` runs it too: it brakes the gap rate $v - \psi_t$.)

# +
piston = sc.load_scene("piston")
if FAST:  # half the grid, the same Δt/Δx
    piston = piston.replace(nx=100, nt=125)
thrown = sc.simulate(piston)
mid = int(np.argmin(np.abs(thrown.x - 0.5)))
psi = np.array([piston.obstacle_values(thrown.x, t) for t in thrown.t])
rising = thrown.t < 0.15
print(f"while rising: max |eta - psi| at the middle {np.max(np.abs(thrown.eta[rising, mid] - psi[rising, mid])):.1e}, "
      f"its speed {thrown.velocity[rising, mid][-1]:.3f}")
print(f"highest flight: eta = {thrown.eta[:, mid].max():.3f} at t = {thrown.t[np.argmax(thrown.eta[:, mid])]:.3f}")
fig, ax = plt.subplots(figsize=(6.5, 3.6), constrained_layout=True)
ax.plot(thrown.t, thrown.eta[:, mid], label="string at x = 1/2")
ax.plot(thrown.t, psi[:, mid], "--", label="piston top ψ(1/2, t)")
ax.set_xlabel("t")
ax.set_ylabel("height")
ax.legend()
piston_picture = OUT / "piston.png"
fig.savefig(piston_picture, dpi=120)
plt.close(fig)
print(f"wrote {piston_picture}")
# -

# The contact force's work on the string, $\tfrac12 F\cdot(\eta^{n+1} - \eta^{n-1})$ per step, splits into
# the obstacle's work $\tfrac12 F\cdot(\psi^{n+1} - \psi^{n-1})$, booked as **external work**, and the work
# on the gap, booked as contact dissipation, which is $\ge 0$ because the constraint holds: the piston
# gives the string energy, the landing takes it. The ledger
# $E(0) + W_\mathrm{ext} = E(t) + D_\mathrm{visc} + D_\mathrm{con} + D_\mathrm{num}$ closes.

b = thrown.checks["energy_balance"]
print(f"piston's work {b['external_work']:.4f} = E(T) {b['final']:.4f} + viscous {b['viscous_dissipation']:.4f} "
      f"+ contact {b['contact_dissipation']:.4f} + numerical {b['numerical_dissipation']:.2g}; "
      f"relative residual {b['relative_residual']:.1e}, closes: {b['closes']}")

# ## Where to go from here
#
# - `stringcontact models` lists every registered model: the paper's `inelastic`, and the two variants in
#   `stringcontact.model.variants`, written the same way: `elastic` (a pure spring, $e = 1$) and
#   `loaded_obstacle` (a load $f(x)$ and an obstacle profile $\psi(x)$ from the scene keys `load` and
#   `obstacle`, which reach the model as P1 functions in `p.extra`).
# - `docs/howto/models.md` lists what each function receives and what the scheme does with it.
