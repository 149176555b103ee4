# ---
# jupytext:
#   text_representation:
#     extension: .py
#     format_name: light
# ---

# # Membranes: the string's model on a 2D mesh
#
# The paper calls its string "a toy problem as a first step" towards contact in fluid-structure
# interaction. The next step is a membrane, a drum skin or a valve leaflet thrown onto an obstacle. Its
# displacement $\eta(t, x, y)$ over a domain $\Omega \subset \mathbb{R}^2$ obeys the same equation with
# the Laplacian in place of $\eta_{xx}$:
#
# $$\eta_{tt} - \alpha\,\Delta\eta_t - \Delta\eta = f + F_\mathrm{con}, \qquad \eta \ge \psi, \qquad
#   \eta = h \text{ on } \partial\Omega .$$
#
# In weak form, for every test function $w$ vanishing on $\partial\Omega$,
#
# $$\int_\Omega \eta_{tt}\,w + \alpha \int_\Omega \nabla\eta_t\cdot\nabla w
#   + \int_\Omega \nabla\eta\cdot\nabla w = \int_\Omega f\,w + \int_\Omega F_\mathrm{con}\,w .$$
#
# That is the string's weak form read in two dimensions: `stringcontact.model.inelastic.momentum_form` is written
# with `grad` and `inner` and never asks for the dimension. Nothing below changes the model, the contact
# law or the time schemes; the scene only gives the membrane a domain.

# +
import inspect
import os
import warnings
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import stringcontact as sc

OUT = Path(os.environ.get("STRINGCONTACT_DEMO_OUT", "out/demo_membrane"))
OUT.mkdir(parents=True, exist_ok=True)

print(inspect.getsource(sc.inelastic.momentum_form))
# -

# ## The drum: a disk skin thrown onto the floor
#
# The scene `drum` is a disk of radius 1 meshed by gmsh, its rim held at $h = 0.3$, thrown down at
# $v_0 = -2(1 - r^2)$ under gravity $f = -10$ onto the flat obstacle $\psi = 0$ (the model
# `loaded_obstacle`, which reads `load` and `obstacle`). It runs with the scheme `projection`: central
# differences with the viscosity implicit, and after each step every node that would pass the obstacle
# is put on it. That is the inelastic law with no $\varepsilon$: a node that lands stops.
# (About 1500 nodes and 200 steps: a second or two, so this demo runs at full size even under
# `STRINGCONTACT_DEMO_FAST=1`.)

drum = sc.load_scene("drum")
print(drum.description)
res = sc.simulate(drum, output=sc.Output(OUT / "drum", force=True))
print(f"{len(res.x)} nodes, {len(res.cells)} triangles, {drum.nt} steps of dt = {drum.dt}")

# The energy books close as in 1D: $E(0) + W_\mathrm{load} = E(T) + D_\mathrm{visc} + D_\mathrm{con}$,
# with no numerical dissipation for this scheme. Gravity does work on the way down, the landing
# destroys it.

e = res.energy
print(f"E(0) = {res.total_energy[0]:.4f}, load's work {e['external_work'][-1]:.4f}, E(T) = {res.total_energy[-1]:.4f}, "
      f"viscous {e['viscous_dissipation'][-1]:.4f}, contact {e['contact_dissipation'][-1]:.4f}, "
      f"numerical {e['numerical_dissipation'][-1]:.2g}; residual {abs(res.balance_residual[-1]):.1e}")
assert abs(res.balance_residual[-1]) < 1e-10 * res.total_energy[0]
print(f"lowest point {res.min_eta:.3g} (the obstacle is 0: the projection never lets it through)")

# The contact region is now an area, $|\{\eta \le \psi\}|$ (`Result.contact_measure`: the lumped nodal
# areas of the nodes in contact), and it can fall apart into patches (`Result.contact_patches()`: the
# connected sets of contact nodes along mesh edges).

patches = res.contact_patches()
for t in drum.output_times:
    k = int(np.argmin(np.abs(res.t - t)))
    print(f"t = {res.t[k]:4.2f}: contact area {res.contact_measure[k]:.3f} of {np.pi:.3f}, {patches[k]} patch(es)")

# Everything here is radially symmetric, so the contact set must be a disk about the centre, up to one
# cell of the unstructured mesh: every node nearer to the centre than the nearest free node is in
# contact. We check it at every stored time with contact.

r = np.hypot(res.x[:, 0], res.x[:, 1])
disk = all(
    row[r < r[~row].min()].all()
    for row in res.contact
    if row.any() and not row.all()
)
print(f"drum: the contact patch is a disk at every stored time: {disk}")

# The run's folder holds `solution.xdmf` (the triangle mesh with η, velocity, contact and contact force
# on one grid per stored time) and the pictures: `membrane.png` (the skin warped by η at the scene's
# output times, red where it touches), `contact_area.png`, `energy.png` and the animation `membrane.gif`.
# In ParaView: open `solution.xdmf` (reader "Xdmf3ReaderT"), *Apply*, then *Filters → Warp By Scalar*
# on `eta` and colour by `contact`; *Play* runs the landing.

print("drum folder:", ", ".join(sorted(p.name for p in (OUT / "drum").iterdir())))

# ## The bump: patches that grow and join
#
# The scene `bump` drops the unit square under gravity onto an obstacle with two Gaussian humps,
#
# $$\psi(x, y) = 0.2\,e^{-((x-0.3)^2 + (y-0.5)^2)/0.01} + 0.2\,e^{-((x-0.7)^2 + (y-0.5)^2)/0.01} - 0.1 .$$
#
# The membrane first touches the two summits: two patches. They grow, the skin between them sags onto the
# floor, and they join into one.

bump = sc.load_scene("bump")
res_bump = sc.simulate(bump)
patches = res_bump.contact_patches()
for t in bump.output_times:
    k = int(np.argmin(np.abs(res_bump.t - t)))
    print(f"t = {res_bump.t[k]:4.2f}: contact area {res_bump.contact_measure[k]:.3f}, {patches[k]} patch(es)")
two = np.flatnonzero(patches == 2)
joined = two.size > 0 and bool(np.any(patches[two[0]:] == 1))
print(f"bump: two patches that join into one: {joined}")

# ## A variant: a skin that bounces
#
# The same drum without gravity, with two contact laws: the paper's inelastic one (scheme `projection`)
# and the built-in variant `elastic`, the Signorini spring $F = \varepsilon^{-1}\eta^-$ that gives the
# energy back (scheme `paper`, explicit; its bound $\Delta t^2/\varepsilon = 0.05 \le 2$ holds). Changing the
# law is naming another model; the mesh, the scheme layer and the output stay.

free = drum.replace(load=None, model=None)  # model=None: the paper's own model, which reads no load
with warnings.catch_warnings():
    warnings.simplefilter("ignore", sc.SceneWarning)
    runs = {"inelastic (projection)": sc.simulate(free, scheme="projection"),
            "elastic (paper, eps = 5e-4)": sc.simulate(free, scheme="paper", model="elastic")}
for name, run in runs.items():
    print(f"{name:28s} contact took {run.energy['contact_dissipation'][-1]:.3f} of E(0) = {run.total_energy[0]:.3f}; "
          f"last contact at t = {run.t[np.flatnonzero(run.contact_measure > 0)[-1]]:.3f}")

# The inelastic skin lands and stays down until the rim's tension peels it off, losing about half its
# energy in contact; the spring throws it back sooner and keeps its energy (what it loses is viscous).

last = [run.t[np.flatnonzero(run.contact_measure > 0)[-1]] for run in runs.values()]
kept = [run.energy["contact_dissipation"][-1] / run.total_energy[0] for run in runs.values()]
print(f"the inelastic skin stays down longer: {last[0] > last[1]}; "
      f"the spring loses under 1% of E(0) in contact: {kept[1] < 0.01}")

fig, ax = plt.subplots(figsize=(7, 4))
for name, run in runs.items():
    ax.plot(run.t, run.contact_measure, label=name)
ax.set_xlabel("t")
ax.set_ylabel("contact area")
ax.set_title("The drum without gravity: inelastic against elastic contact")
ax.legend()
ax.grid(alpha=0.3)
fig.savefig(OUT / "drum_variants.png", dpi=100)
print("wrote", OUT / "drum_variants.png")
