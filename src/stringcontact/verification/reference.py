r"""Plain-NumPy finite differences for the string, written independently of the package: the ``projection`` scheme
(`fd_projection`) and the paper's Section 6 scheme (`fd_solve`), with fixed ends, v^n = (η^n − η^{n−1})/Δt and
η^{−1} = η^0 − Δt v_0 inside, :math:`(\eta_j^{n+1} - 2\eta_j^n + \eta_j^{n-1})/\Delta t^2 - \alpha(D^2\eta^{n+1} -
D^2\eta^n)_j/\Delta t - (D^2\eta^{n+1})_j = F_j^n`: ``penalty="explicit"`` F = ε⁻¹ χ{η^n < 0} (v^n)⁻, or
``"semi-implicit"`` F = −ε⁻¹ χ{η^n < 0, v^n < 0} (η^{n+1} − η^n)/Δt (``eps=numpy.inf``: no contact)."""

import numpy as np
from scipy.linalg import solve_banded

PENALTIES = ("explicit", "semi-implicit")


def second_difference(eta, dx):
    r"""Interior second difference :math:`(\eta_{j+1} - 2\eta_j + \eta_{j-1})/\Delta x^2`, ``j = 1..N-1``."""
    return (eta[2:] - 2.0 * eta[1:-1] + eta[:-2]) / dx**2


def _stored_steps(nt: int, store_every: int) -> list[int]:
    """Steps 0, store_every, 2 store_every, ... and always the last, nt."""
    steps = list(range(0, nt + 1, store_every))
    return steps if steps[-1] == nt else [*steps, nt]


class StoredRows:
    """The rows of η and v at `steps` of a string of `n` nodes: ``rows(step, eta, v)`` at every step keeps those."""

    def __init__(self, steps, n: int):
        self.steps, self.row = steps, 0
        self.eta, self.v = np.empty((len(steps), n)), np.empty((len(steps), n))

    def __call__(self, step: int, eta, v) -> None:
        if self.row < len(self.steps) and self.steps[self.row] == step:
            self.eta[self.row], self.v[self.row] = eta, v
            self.row += 1


def _start(eta0, v0, dt, h_left, h_right, psi=None):
    """(η⁰, η⁻¹): ``eta0`` with its ends at h_left/h_right (inside raised onto ψ, if given), η⁰ − Δt v0 inside."""
    eta = np.asarray(eta0, dtype=float).copy()
    eta[0], eta[-1] = h_left, h_right
    if psi is not None:
        eta[1:-1] = np.maximum(eta[1:-1], psi[1:-1])
    eta_prev = eta.copy()
    eta_prev[1:-1] -= dt * np.asarray(v0, dtype=float)[1:-1]
    return eta, eta_prev


def fd_solve(eta0, v0, *, length, T, nt, alpha, eps, h_left, h_right, penalty="explicit", store_every=1):
    """March the Section 6 scheme from (η⁰, v⁰) to t = T in ``nt`` steps, each a tridiagonal system solved by LAPACK's
    banded solver: ``(t, eta, velocity)``, rows at steps 0, store_every, 2 store_every, ... and nt."""
    eta0, v0 = np.asarray(eta0, dtype=float), np.asarray(v0, dtype=float)
    if eta0.ndim != 1 or eta0.shape != v0.shape or eta0.size < 3:
        raise ValueError(f"eta0 and v0 must be 1-D arrays of one shape with >= 3 nodes, got {eta0.shape}, {v0.shape}")
    for name, value in (("nt", nt), ("store_every", store_every)):
        if int(value) != value or value < 1:
            raise ValueError(f"{name} must be a positive integer, got {value}")
    if penalty not in PENALTIES:
        raise ValueError(f"penalty must be one of {PENALTIES}, got {penalty!r}")
    if not (eps > 0 and length > 0 and T > 0 and alpha >= 0):
        raise ValueError(f"need eps > 0 (numpy.inf: no contact), length > 0, T > 0, alpha >= 0, got {eps}, {length}, "
                         f"{T}, {alpha}")
    nt, N = int(nt), eta0.size - 1
    dx, dt = length / N, T / nt
    inv_eps = 0.0 if np.isinf(eps) else 1.0 / eps
    r = (alpha * dt + dt**2) / dx**2
    eta, eta_prev = _start(eta0, v0, dt, h_left, h_right)
    bands = np.empty((3, N - 1))  # solve_banded's rows: super-, main and sub-diagonal
    bands[0, :] = bands[2, :] = -r
    main = np.full(N - 1, 1.0 + 2.0 * r)
    rows = StoredRows(_stored_steps(nt, int(store_every)), N + 1)
    rows(0, eta, (eta - eta_prev) / dt)
    for n in range(nt):
        v = (eta[1:-1] - eta_prev[1:-1]) / dt
        rhs = 2.0 * eta[1:-1] - eta_prev[1:-1] - alpha * dt * second_difference(eta, dx)
        rhs[0] += r * h_left  # the new end values are known
        rhs[-1] += r * h_right
        if penalty == "explicit":
            rhs += dt**2 * (inv_eps * (eta[1:-1] < 0.0) * np.maximum(-v, 0.0))  # Δt² F
            bands[1, :] = main
        else:
            damping = (dt * inv_eps) * ((eta[1:-1] < 0.0) & (v < 0.0))
            rhs += damping * eta[1:-1]
            bands[1, :] = main + damping
        eta_next = eta.copy()  # the ends stay at h_left, h_right
        eta_next[1:-1] = solve_banded((1, 1), bands, rhs, overwrite_ab=False, check_finite=False)
        eta_prev, eta = eta, eta_next
        rows(n + 1, eta, (eta - eta_prev) / dt)
    return dt * np.asarray(rows.steps, dtype=float), rows.eta, rows.v


def fd_projection(eta0, v0, *, length, T, nt, alpha, h_left, h_right, obstacle=None, store_every=1, nodal=False):
    r"""The ``projection`` scheme in finite differences, with ψ the nodal ``obstacle`` (0 if None) and η⁰ raised onto
    it: each step the complementarity problem :math:`f = \eta^{n+1} - \alpha\Delta t\, D^2(\eta^{n+1} - \eta^n) -
    2\eta^n + \eta^{n-1} - \Delta t^2 D^2\eta^n \ge 0`, :math:`\eta^{n+1} \ge \psi`, :math:`f(\eta^{n+1} - \psi) = 0`
    by projected red-black Gauss-Seidel (not the package's active set) from the nodal maximum, the solution at α = 0
    (``nodal=True``: that maximum at any α). ``(t, eta, velocity)`` as `fd_solve`, the velocity centred after t = 0."""
    N = np.size(eta0) - 1
    dx, dt = length / N, T / int(nt)
    psi = np.zeros(N + 1) if obstacle is None else np.asarray(obstacle, dtype=float)
    s = alpha * dt / dx**2
    bands = np.empty((3, N - 1))
    bands[0, :], bands[1, :], bands[2, :] = -s, 1.0 + 2.0 * s, -s
    eta, eta_prev = _start(eta0, v0, dt, h_left, h_right, psi)
    rows = StoredRows(_stored_steps(int(nt), store_every), N + 1)
    rows(0, eta, (eta - eta_prev) / dt)
    for n in range(int(nt) + 1):  # computes η^{n+1}; the last one only for the velocity at T
        d2 = second_difference(eta, dx)
        rhs = 2.0 * eta[1:-1] - eta_prev[1:-1] + dt**2 * d2 - s * dx**2 * d2
        rhs[0] += s * h_left  # the ends' part of −αΔt D²η^{n+1} is known
        rhs[-1] += s * h_right
        new = eta.copy()  # the ends stay at h_left, h_right
        new[1:-1] = solve_banded((1, 1), bands, rhs, check_finite=False) if alpha > 0 else rhs
        new[1:-1] = np.maximum(new[1:-1], psi[1:-1])
        if alpha > 0 and not nodal:
            _projected_gauss_seidel(new, rhs, s, psi)
        rows(n, eta, (new - eta_prev) / (2.0 * dt))  # η^n with the centred velocity
        eta_prev, eta = eta, new
    return dt * np.asarray(rows.steps, dtype=float), rows.eta, rows.v


def _projected_gauss_seidel(eta, rhs, s, psi, rtol=1e-15, max_sweeps=100_000):
    """(1 + 2s) η_j − s(η_{j−1} + η_{j+1}) ≥ rhs_j, η_j ≥ ψ_j, complementary, solved in place on the interior by
    red-black sweeps η_j ← max(ψ_j, (rhs_j + s(η_{j−1} + η_{j+1}))/(1 + 2s)) until none moves by `rtol` of max |η|."""
    scale = max(float(np.max(np.abs(eta))), 1e-300)
    if not np.isfinite(scale):  # an unstable run (the stability map's): nothing to converge to
        return
    w = eta.copy()
    w[0] = w[-1] = 0.0  # the ends' part is in rhs already
    inner = w[1:-1]
    for _ in range(max_sweeps):
        old = inner.copy()
        for first in (1, 2):  # odd nodes, then even: each colour's neighbours are of the other colour
            j = np.arange(first, w.size - 1, 2)
            w[j] = np.maximum(psi[j], (rhs[j - 1] + s * (w[j - 1] + w[j + 1])) / (1.0 + 2.0 * s))
        if np.max(np.abs(inner - old)) <= rtol * scale:
            eta[1:-1] = inner
            return
    raise RuntimeError("projected Gauss-Seidel did not converge")
