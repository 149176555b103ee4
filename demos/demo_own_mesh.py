# ---
# jupytext:
#   text_representation:
#     extension: .py
#     format_name: light
# ---

# # Your own mesh and Functions: the core as a library
#
# A FEniCSx user has a mesh already: from gmsh, graded towards where the action is, or a membrane from
# their own pipeline. stringcontact's core takes those objects as they are. A `ContactProblem` is the
# model on *your* P1 space, with *your* Functions $\eta$ and $v$ and *your* `DirichletBC`s; a
# `TimeStepper` advances them in place, one step per `advance()`, as dolfinx's `NonlinearProblem` or
# Irksome's `TimeStepper` do. No scene file is involved.
#
# The equation is the paper's, on any domain $\Omega$ (an interval, a 2D mesh):
#
# $$\eta_{tt} - \alpha\,\Delta\eta_t - \Delta\eta = f + F_\mathrm{con}, \qquad \eta \ge \psi, \qquad
#   \eta = h \text{ on } \partial\Omega .$$

# On dolfinx's PyPI wheel, MPI must be loaded before dolfinx: importing stringcontact first does that
# (elsewhere it changes nothing).

# +
import stringcontact as sc  # isort: skip

import os
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import ufl
from dolfinx import fem, io, mesh
from mpi4py import MPI

from stringcontact.fem import compat

OUT = Path(os.environ.get("STRINGCONTACT_DEMO_OUT", "out/demo_own_mesh"))
OUT.mkdir(parents=True, exist_ok=True)
FAST = os.environ.get("STRINGCONTACT_DEMO_FAST") == "1"  # reduced resolution for the test suite
# -

# ## A string on a graded mesh
#
# Example 1's string, thrown down onto the floor $\psi = 0$, on 600 cells crowded towards the middle,
# where it lands: the cells there are three times smaller than at the ends. Any dolfinx mesh of an
# interval would do; here the nodes of a uniform one are moved.

# +
cells = 200 if FAST else 600
msh = mesh.create_interval(MPI.COMM_WORLD, cells, [0.0, 1.0])
s = msh.geometry.x[:, 0].copy()
msh.geometry.x[:, 0] = s - np.sin(2 * np.pi * s) / (3 * np.pi)  # graded: dx/ds = 1 - (2/3) cos(2 pi s)
V = compat.function_space(msh, "Lagrange", 1)

eta, v = fem.Function(V, name="eta"), fem.Function(V, name="v")
eta.interpolate(lambda x: 1.0 + 0.5 * np.sin(10 * np.pi * x[0]) ** 2)
v.interpolate(lambda x: -30.0 * np.ones_like(x[0]))
ends = fem.locate_dofs_geometrical(V, lambda x: np.isclose(x[0], 0.0) | np.isclose(x[0], 1.0))
bc = fem.dirichletbc(np.float64(1.0), ends, V)

problem = sc.ContactProblem(sc.inelastic, eta, v, bcs=[bc], alpha=0.01)
# -

# The scheme is `newmark` (the trapezoidal rule, unconditionally stable, so the smallest cell does not
# bound $\Delta t$) with its semi-implicit penalty; its options are keywords, checked against what the
# scheme declares (`ProjectionScheme.OPTIONS`, `NewmarkScheme.OPTIONS`, ...).

# +
T, dt = 0.3, 2e-4
stepper = sc.TimeStepper(problem, dt, scheme="newmark", eps=5e-4)


class Lowest:
    """An observer: the lowest point and the contact length after every step."""

    def __init__(self):
        self.t, self.low, self.contact = [], [], []
        self.cell = fem.form(ufl.conditional(ufl.le(eta, 1e-3), 1.0, 0.0) * ufl.dx)

    def stepped(self, st):
        self.t.append(st.t)
        self.low.append(eta.x.array.min())
        self.contact.append(fem.assemble_scalar(self.cell))


lowest = stepper.attach(Lowest())
with io.XDMFFile(msh.comm, str(OUT / "string.xdmf"), "w") as xdmf:  # dolfinx's own writer, as always
    xdmf.write_mesh(msh)
    while stepper.t < T - dt / 2:
        stepper.advance()  # eta and v now hold t + dt
        if stepper.step % 150 == 0:
            xdmf.write_function(eta, stepper.t)
ledger = stepper.ledger
print(f"t = {stepper.t:.3f}: min eta = {min(lowest.low):.4f}, contact dissipation {ledger.con:.1f} of E(0) = "
      f"{ledger.E_start:.1f}, balance residual {abs(ledger.residual):.1e}")
assert abs(ledger.residual) < 1e-9 * ledger.E_start
# -

# The energy books close to round-off on the graded mesh as on a uniform one, and the contact force
# of the last step is a Function too (`stepper.contact_force`).

fig, (a, b) = plt.subplots(1, 2, figsize=(9, 3.2))
a.plot(lowest.t, lowest.low)
a.set(xlabel="t", ylabel="min η")
b.plot(lowest.t, lowest.contact)
b.set(xlabel="t", ylabel="contact length |{η ≤ 0.001}|")
fig.tight_layout()
fig.savefig(OUT / "string.png")

# ## A membrane of your own
#
# A rectangle skin $[0, 2] \times [0, 1]$, held at $h = 0.2$ on its edge, falls under gravity
# $f = -10$ onto a bump $\psi(x, y) = 0.1\,e^{-20((x-1)^2 + (y-0.5)^2)}$. The model
# `loaded_obstacle` reads the load and the obstacle as P1 fields, which are plain Functions here.
# The scheme is `projection`, free of $\varepsilon$: after each step, every node below the obstacle
# is put on it.

# +
n = 16 if FAST else 32
skin = mesh.create_rectangle(MPI.COMM_WORLD, [np.zeros(2), np.array([2.0, 1.0])], [2 * n, n],
                             mesh.CellType.triangle)
W = compat.function_space(skin, "Lagrange", 1)
height, speed = fem.Function(W, name="eta"), fem.Function(W, name="v")
height.x.array[:] = 0.2
load, bump = fem.Function(W, name="load"), fem.Function(W, name="obstacle")
load.x.array[:] = -10.0
bump.interpolate(lambda x: 0.1 * np.exp(-20 * ((x[0] - 1) ** 2 + (x[1] - 0.5) ** 2)))
rim = fem.locate_dofs_geometrical(W, lambda x: np.isclose(x[0], 0) | np.isclose(x[0], 2) | np.isclose(x[1], 0)
                                  | np.isclose(x[1], 1))
membrane = sc.ContactProblem(sc.load_model("loaded_obstacle"), height, speed,
                             bcs=[fem.dirichletbc(np.float64(0.2), rim, W)], alpha=0.02,
                             fields={"load": load, "obstacle": bump})
skin_stepper = sc.TimeStepper(membrane, dt=2e-3, scheme="projection")
for _ in range(150):
    skin_stepper.advance()
touching = np.flatnonzero(height.x.array <= bump.x.array + 1e-12)
print(f"t = {skin_stepper.t:.2f}: {touching.size} nodes on the bump, lowest point {height.x.array.min():.3f}, "
      f"balance residual {abs(skin_stepper.ledger.residual):.1e}")
assert height.x.array.min() >= bump.x.array.min() - 1e-12
# -

# ## The same problem through a scene
#
# A scene is an adapter over this core: `simulate("example1")` builds the interval, the Functions and
# the boundary conditions from the scene's keys, and steps the same `TimeStepper`. Built by hand on
# the same uniform mesh, the run gives the scene's numbers to the bit.

# +
scene = sc.load_scene("example1").replace(nx=500, nt=750, output_times=[])
by_scene = sc.simulate(scene, scheme="projection")
line = mesh.create_interval(MPI.COMM_WORLD, 500, [0.0, 1.0])
U = compat.function_space(line, "Lagrange", 1)
h, u = fem.Function(U), fem.Function(U)
x = U.tabulate_dof_coordinates()[:, 0]
h.x.array[:], u.x.array[:] = scene.initial_displacement(x), scene.initial_velocity(x)
fixed = fem.locate_dofs_geometrical(U, lambda x: np.isclose(x[0], 0.0) | np.isclose(x[0], 1.0))
by_hand = sc.TimeStepper(sc.ContactProblem(sc.inelastic, h, u, bcs=[fem.dirichletbc(np.float64(1.0), fixed, U)],
                                           alpha=scene.alpha), scene.dt, scheme="projection", nt=scene.nt)
for _ in range(scene.nt):
    by_hand.advance()
same = np.array_equal(h.x.array[np.argsort(x)], by_scene.eta[-1])
print(f"eta(T) by hand and by the scene identical: {same}")
assert same
# -
