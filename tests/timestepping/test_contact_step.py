"""The ε-free scheme's contact step is the complementarity problem A η = b + F, η ≥ ψ, F ≥ 0, F·(η − ψ) = 0.

Checked against an independent NumPy solver of the same problem (projected Gauss-Seidel in
`reference.fd_projection`), against the nodal maximum where the two must agree (α = 0), and for what the
stored `contact_force` promises on every built-in scene and scheme. No timing here: the costs are in
benchmarks/bench_contact_step.py.
"""

import subprocess
import sys
import warnings

import numpy as np
import pytest
from mpi4py import MPI

import stringcontact as sc
from stringcontact.analysis import study
from stringcontact.model.registry import load_model
from stringcontact.timestepping import check_model, complementarity
from stringcontact.verification import reference


def run(scene, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # example2 starts below the obstacle, as printed
        return sc.simulate(scene, comm=MPI.COMM_SELF, **kwargs)


def fd_projection(scene, **kwargs):
    x = scene.x()
    return reference.fd_projection(
        scene.initial_displacement(x), scene.initial_velocity(x), length=scene.length, T=scene.T, nt=scene.nt,
        alpha=scene.alpha, h_left=scene.h_left, h_right=scene.h_right, **kwargs,
    )


@pytest.mark.parametrize("name", ["example1", "example2"])
def test_without_viscosity_the_step_is_the_nodal_maximum(name):
    scene = sc.load_scene(name).replace(nx=300, nt=600, alpha=0.0)  # A = M/Δt²: diagonal
    res = run(scene, scheme="projection")
    _, nodal, _ = fd_projection(scene, nodal=True)
    assert res.contact.any()
    assert np.max(np.abs(res.eta - nodal[res.steps])) <= 1e-10 * np.max(np.abs(nodal))


@pytest.mark.parametrize("name", ["example1", "example2"])
def test_with_viscosity_the_step_solves_the_complementarity_problem(name):
    scene = sc.load_scene(name).replace(nx=300, nt=600)
    res = run(scene, scheme="projection")
    _, eta, vel = fd_projection(scene)
    _, nodal, _ = fd_projection(scene, nodal=True)
    scale = np.max(np.abs(eta))
    assert np.max(np.abs(res.eta - eta[res.steps])) <= 1e-10 * scale
    assert np.max(np.abs(res.velocity - vel[res.steps])) <= 1e-10 * scale / scene.dt
    assert np.max(np.abs(res.eta - nodal[res.steps])) >= 1e-4 * scale  # a different step from the nodal maximum


def _schemes_for(scene):
    model = load_model(scene.model) if scene.model else sc.inelastic
    usable = []
    for name in sc.SCHEMES:
        try:
            check_model(name, model)
        except ValueError:
            continue
        usable.append(name)
    return usable


def _small(scene):
    """A coarse copy with r = Δt/ε ≤ 1, so that the paper's explicit penalty runs too."""
    if scene.dim == 2:
        scene = scene.replace(mesh_size=0.2) if scene.domain == "disk" else scene.replace(cells=[10, 10])
    else:
        scene = scene.replace(nx=200, nt=max(200, round(scene.nt * 200 / scene.nx)))
    return scene.replace(eps=max(scene.eps, scene.dt))


CASES = [(name, scheme) for name, _ in sc.list_scenes() for scheme in _schemes_for(sc.load_scene(name))]


@pytest.mark.slow
@pytest.mark.parametrize("name, scheme", CASES)
def test_the_stored_contact_force_is_a_contact_force(name, scheme):
    """(A1) F ≥ 0 and (A2) F = 0 off the contact set, at every stored time, for every scene and scheme."""
    res = run(_small(sc.load_scene(name)), scheme=scheme)
    F = res.contact_force
    assert res.status == "complete", res.message
    assert F.max() > 0.0  # the scene has contact: the check is not vacuous
    assert np.all(F >= 0.0), F.min()
    assert np.all(F[~res.contact] == 0.0)


def test_projection_books_the_contact_force_s_work_and_closes():
    scene = sc.load_scene("example1").replace(nx=200, nt=300)
    res = run(scene, scheme="projection", storage=sc.Storage(max_rows=scene.nt))  # every step
    m = reference_weights(res.x)
    # the contact dissipation of step n is −½ m F^n·(η^n − η^{n−2}) (F the density), with η^{−1} = η^0 − Δt v0
    eta = np.concatenate([[res.eta[0] - scene.dt * res.velocity[0]], res.eta])
    work = -0.5 * np.sum(m * res.contact_force[1:] * (eta[2:] - eta[:-2]), axis=1)
    e = res.energy
    assert np.all(work >= 0.0)
    assert np.allclose(np.cumsum(work), e["contact_dissipation"][1:], rtol=1e-12, atol=1e-12 * res.total_energy[0])
    assert np.all(e["numerical_dissipation"] == 0.0)
    assert np.max(np.abs(res.balance_residual)) <= 1e-11 * res.total_energy[0]


def reference_weights(x):
    dx = np.diff(x)
    m = np.zeros_like(x)
    m[:-1] += 0.5 * dx
    m[1:] += 0.5 * dx
    return m


def test_the_stored_velocity_is_centred_and_starts_at_v0():
    scene = sc.load_scene("example1").replace(nx=100, nt=150)
    res = run(scene, scheme="projection", storage=sc.Storage(max_rows=scene.nt))
    v0 = scene.initial_velocity(res.x)
    assert np.array_equal(res.velocity[0][1:-1], v0[1:-1])
    centred = (res.eta[2:] - res.eta[:-2]) / (2 * scene.dt)
    assert np.allclose(res.velocity[1:-1], centred, rtol=0, atol=1e-9 * np.max(np.abs(centred)))
    on = res.eta == 0.0  # held on the obstacle by the contact step (ψ = 0), not merely within CONTACT_TOL of it
    resting = on[:-2] & on[1:-1] & on[2:]  # at t_{n−1}, t_n and t_{n+1}
    assert resting.any()
    assert np.all(res.velocity[1:-1][resting] == 0.0)  # (A4): at rest, exactly


def test_the_velocity_converges_on_the_flat_landing():
    errors = []
    for n in (250, 500, 1000):  # Δt = Δx, α = 0: the exact solution is known
        r = study.run_method(study.flat_landing_scene(n), study.METHODS["projection"])
        errors.append(study.errors_against_exact(r, study.flat_landing_exact)["err_vel"])
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < 0.6 * errors[0]  # about order ½ (the one-sided quotient stayed at 0.45 to 0.52)


def test_snes_vi_gives_the_active_set_s_answer(monkeypatch):
    scene = sc.load_scene("example1").replace(nx=200, nt=300)
    active = run(scene, scheme="projection")
    monkeypatch.setattr(complementarity, "MAX_ITERATIONS", 0)  # every step by PETSc's SNES VI
    vi = run(scene, scheme="projection")
    assert "SNES VI fallbacks" in vi.solver["contact step"]
    assert np.max(np.abs(vi.eta - active.eta)) <= 1e-9 * np.max(np.abs(active.eta))
    assert np.max(np.abs(vi.contact_force - active.contact_force)) <= 1e-8 * np.max(active.contact_force)


def test_a_cycling_active_set_falls_back_to_snes_vi():
    """An SPD matrix that is not an M-matrix (found by a random search; every iterate is at least 1e-3 away
    from a tie): the active-set method started from 𝒜 = ∅ comes back to a set it had after 3 iterations; the
    step then ends in SNES VI, at the LCP's solution."""
    from petsc4py import PETSc

    A_dense = np.array([[4.85, 5.17, -0.72, -4.81], [5.17, 7.48, -0.67, -4.31], [-0.72, -0.67, 0.76, 1.22],
                        [-4.81, -4.31, 1.22, 5.81]])
    b_dense = np.array([1.17, 0.14, 0.16, -1.22])
    n = b_dense.size
    A = PETSc.Mat().createAIJ(size=(n, n), comm=MPI.COMM_SELF)
    A.setUp()
    A.setValues(range(n), range(n), A_dense)
    A.assemble()
    psi, none = np.zeros(n), np.zeros(0, dtype=np.int32)
    step = complementarity.ActiveSet(A, MPI.COMM_SELF, None, none, np.zeros(0), 1, psi, np.ones(n, bool),
                                     force_tol=np.zeros(n))
    b, x = A.createVecLeft(), A.createVecRight()
    b.array[:] = b_dense

    def residual(eta):
        return A_dense @ eta - b_dense

    F, _ = step.solve(b, x, residual)
    assert step.fallbacks == 1
    solution = _lcp_by_enumeration(A_dense, b_dense)
    assert np.allclose(x.array, solution, atol=1e-12)
    assert np.allclose(F, A_dense @ solution - b_dense, atol=1e-10) and np.all(F >= 0)


def _lcp_by_enumeration(A, b):
    """The η ≥ 0 with Aη − b ≥ 0 and η·(Aη − b) = 0, by trying every active set."""
    n = b.size
    for mask in range(2**n):
        active = np.array([(mask >> i) & 1 for i in range(n)], dtype=bool)
        eta = np.zeros(n)
        free = ~active
        if free.any():
            eta[free] = np.linalg.solve(A[np.ix_(free, free)], b[free])
        if np.all(eta >= -1e-14) and np.all((A @ eta - b)[active] >= -1e-12):
            return eta
    raise AssertionError("no solution")


@pytest.mark.slow
def test_check_runs_on_the_projection_scheme():
    proc = subprocess.run([sys.executable, "-m", "stringcontact", "check", "example1", "--scheme", "projection",
                           "--nx", "800", "--nt", "240", "--levels", "2"], capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr
    assert "scheme projection" in proc.stdout and "(no eps)" in proc.stdout
    rows = {line.split("  ")[0]: line.split() for line in proc.stdout.splitlines() if line.startswith("(A")}
    assert rows["(A1) F >= 0, D = F(eta_t)^- >= 0"][-1] == "holds"
    a4 = rows["(A4) |v| after contact / impact speed"]
    assert float(a4[7]) <= 1e-5 and a4[-1] in ("holds", "limit")  # "holds in the limit": the last word
