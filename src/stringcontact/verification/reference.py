r"""Plain-NumPy finite-difference reference for the penalised string (paper, Section 6).

On the uniform grid :math:`x_j = j\,\Delta x`, :math:`j = 0..N`, :math:`\Delta x = l/N`,
:math:`\Delta t = T/n_t`, the scheme at the interior nodes :math:`j = 1..N-1` is

.. math::

    \frac{\eta_j^{n+1} - 2\eta_j^n + \eta_j^{n-1}}{\Delta t^2}
    - \frac{\alpha}{\Delta t}\bigl(D^2\eta^{n+1} - D^2\eta^n\bigr)_j
    - (D^2\eta^{n+1})_j = F_j^n,
    \qquad
    (D^2\eta)_j = \frac{\eta_{j+1} - 2\eta_j + \eta_{j-1}}{\Delta x^2},

with fixed ends :math:`\eta_0^n = h_\mathrm{left}`, :math:`\eta_N^n = h_\mathrm{right}` and
:math:`v^n = (\eta^n - \eta^{n-1})/\Delta t`. The contact force :math:`F^n` is

* ``penalty="explicit"`` (the paper's choice):
  :math:`F_j^n = \varepsilon^{-1}\chi\{\eta_j^n < 0\}\,(v_j^n)^-`, with :math:`f^- = \max(-f, 0)`;
* ``penalty="semi-implicit"``: on the same active set :math:`\chi_j^n = \chi\{\eta_j^n < 0,\ v_j^n < 0\}`,
  :math:`F_j^n = -\varepsilon^{-1}\chi_j^n\,(\eta_j^{n+1} - \eta_j^n)/\Delta t`, i.e. the penalty acts on
  the *new* velocity, as a linear implicit damping on the active nodes.

Start-up conventions:

* :math:`\eta^0` is ``eta0`` with its two end values overwritten by ``h_left`` / ``h_right``;
* :math:`\eta^{-1} = \eta^0 - \Delta t\,v_0` at the interior nodes and :math:`\eta^{-1} = \eta^0` at the
  two end nodes (a nonzero ``v0`` at a fixed end contradicts the fixed end, so the end velocity is 0).
  Hence the stored velocity at step 0 is ``v0`` inside and 0 at the ends.

``eps=numpy.inf`` switches the contact force off.
"""

import numpy as np
from scipy.linalg import solve_banded

PENALTIES = ("explicit", "semi-implicit")


def second_difference(eta, dx):
    r"""Interior second difference :math:`(\eta_{j+1} - 2\eta_j + \eta_{j-1})/\Delta x^2`, ``j = 1..N-1``."""
    return (eta[2:] - 2.0 * eta[1:-1] + eta[:-2]) / dx**2


def fd_solve(eta0, v0, *, length, T, nt, alpha, eps, h_left, h_right, penalty="explicit", store_every=1):
    r"""March the Section 6 scheme from :math:`(\eta^0, v^0)` to :math:`t = T` in ``nt`` steps.

    Multiplying the scheme by :math:`\Delta t^2` gives, with :math:`r = (\alpha\Delta t + \Delta t^2)/\Delta x^2`,
    the tridiagonal system for the interior unknowns

    .. math::

        (1 + 2r + c_j)\,\eta_j^{n+1} - r(\eta_{j-1}^{n+1} + \eta_{j+1}^{n+1})
        = 2\eta_j^n - \eta_j^{n-1} - \alpha\Delta t\,(D^2\eta^n)_j + b_j,

    (the known end values :math:`r h` move to the right-hand side), where :math:`c_j = 0`,
    :math:`b_j = \Delta t^2 F_j^n` for the explicit penalty and :math:`c_j = (\Delta t/\varepsilon)\chi_j^n`,
    :math:`b_j = c_j \eta_j^n` for the semi-implicit one.

    Returns ``(t, eta, velocity)``: ``t`` has shape ``(k,)``; ``eta`` and ``velocity`` have shape
    ``(k, N+1)``, rows at steps ``0, store_every, 2*store_every, ...`` and always the last step ``nt``.
    """
    eta0 = np.asarray(eta0, dtype=float)
    v0 = np.asarray(v0, dtype=float)
    if eta0.ndim != 1 or eta0.shape != v0.shape:
        raise ValueError(f"eta0 and v0 must be 1-D arrays of the same shape, got {eta0.shape} and {v0.shape}")
    if eta0.size < 3:
        raise ValueError(f"need at least 3 nodes (one interior node), got {eta0.size}")
    if int(nt) != nt or nt < 1:
        raise ValueError(f"nt must be a positive integer, got {nt}")
    if int(store_every) != store_every or store_every < 1:
        raise ValueError(f"store_every must be a positive integer, got {store_every}")
    if penalty not in PENALTIES:
        raise ValueError(f"penalty must be one of {PENALTIES}, got {penalty!r}")
    if not eps > 0:
        raise ValueError(f"eps must be positive (numpy.inf disables contact), got {eps}")
    if not (length > 0 and T > 0 and alpha >= 0):
        raise ValueError(f"need length > 0, T > 0, alpha >= 0, got {length}, {T}, {alpha}")
    nt, store_every = int(nt), int(store_every)

    N = eta0.size - 1
    dx = length / N
    dt = T / nt
    inv_eps = 0.0 if np.isinf(eps) else 1.0 / eps
    r = (alpha * dt + dt**2) / dx**2

    eta = eta0.copy()
    eta[0], eta[-1] = h_left, h_right
    eta_prev = eta.copy()
    eta_prev[1:-1] -= dt * v0[1:-1]

    # Banded storage for solve_banded((1, 1), ...): rows are super-, main and sub-diagonal.
    # The end entries of the off-diagonals are outside the matrix and ignored.
    bands = np.empty((3, N - 1))
    bands[0, :] = -r
    bands[2, :] = -r
    main = np.full(N - 1, 1.0 + 2.0 * r)

    stored_steps = list(range(0, nt + 1, store_every))
    if stored_steps[-1] != nt:
        stored_steps.append(nt)
    t_out = dt * np.asarray(stored_steps, dtype=float)
    eta_out = np.empty((len(stored_steps), N + 1))
    vel_out = np.empty((len(stored_steps), N + 1))
    eta_out[0] = eta
    vel_out[0] = (eta - eta_prev) / dt
    k = 1

    for n in range(nt):
        v = (eta[1:-1] - eta_prev[1:-1]) / dt
        rhs = 2.0 * eta[1:-1] - eta_prev[1:-1] - alpha * dt * second_difference(eta, dx)
        # The new end values are known (Dirichlet), so they move to the right-hand side.
        rhs[0] += r * h_left
        rhs[-1] += r * h_right

        if penalty == "explicit":
            force = inv_eps * (eta[1:-1] < 0.0) * np.maximum(-v, 0.0)
            rhs += dt**2 * force
            bands[1, :] = main
        else:
            damping = (dt * inv_eps) * ((eta[1:-1] < 0.0) & (v < 0.0))
            rhs += damping * eta[1:-1]
            bands[1, :] = main + damping

        eta_next = np.empty_like(eta)
        eta_next[0], eta_next[-1] = h_left, h_right
        eta_next[1:-1] = solve_banded((1, 1), bands, rhs, overwrite_ab=False, check_finite=False)
        eta_prev, eta = eta, eta_next

        if k < len(stored_steps) and stored_steps[k] == n + 1:
            eta_out[k] = eta
            vel_out[k] = (eta - eta_prev) / dt
            k += 1

    return t_out, eta_out, vel_out


def fd_projection(eta0, v0, *, length, T, nt, alpha, h_left, h_right, obstacle=None, store_every=1, nodal=False):
    r"""The ``projection`` scheme as finite differences: central differences, implicit viscosity, contact step.

    At the interior nodes, with :math:`D^2` the second difference and :math:`\psi` the obstacle (0 unless
    ``obstacle`` gives nodal values), the step is the complementarity problem

    .. math::

        \eta^{n+1} - \alpha\Delta t\, D^2(\eta^{n+1} - \eta^n) - 2\eta^n + \eta^{n-1} - \Delta t^2 D^2\eta^n = f
        \ge 0, \qquad \eta^{n+1} \ge \psi, \qquad f\,(\eta^{n+1} - \psi) = 0,

    solved by projected red-black Gauss-Seidel to round-off (an algorithm of its own, independent of the
    package's active-set solver): start from the nodal maximum and sweep
    :math:`\eta_j \leftarrow \max(\psi_j, \text{the row's solve for } \eta_j)` until nothing changes. For
    α = 0 the rows are uncoupled and that is the nodal maximum itself. ``nodal=True`` takes the nodal
    maximum :math:`\max(\tilde\eta, \psi)` of the free step for any α (the scheme before the contact step
    was a complementarity problem; kept to compare against).

    Start: :math:`\eta^0` is ``eta0`` with its ends at ``h_left``/``h_right``, raised onto ψ where it is
    below it, and :math:`\eta^{-1} = \eta^0 - \Delta t\,v_0` inside. Returns ``(t, eta, velocity)`` as
    `fd_solve` does, with the scheme's stored velocity: ``v0`` at t = 0 (0 at the ends), then the centred
    :math:`(\eta^{n+1} - \eta^{n-1})/(2\Delta t)` (so one step past T is computed).
    """
    eta0 = np.asarray(eta0, dtype=float)
    v0 = np.asarray(v0, dtype=float)
    N = eta0.size - 1
    dx, dt = length / N, T / int(nt)
    psi = np.zeros(N + 1) if obstacle is None else np.asarray(obstacle, dtype=float)
    s = alpha * dt / dx**2
    bands = np.empty((3, N - 1))
    bands[0, :], bands[1, :], bands[2, :] = -s, 1.0 + 2.0 * s, -s

    eta = eta0.copy()
    eta[0], eta[-1] = h_left, h_right
    eta[1:-1] = np.maximum(eta[1:-1], psi[1:-1])
    eta_prev = eta.copy()
    eta_prev[1:-1] -= dt * v0[1:-1]

    steps = list(range(0, int(nt) + 1, store_every))
    if steps[-1] != nt:
        steps.append(int(nt))
    eta_out, vel_out = np.empty((len(steps), N + 1)), np.empty((len(steps), N + 1))
    eta_out[0], vel_out[0] = eta, (eta - eta_prev) / dt
    k = 1
    for n in range(int(nt) + 1):  # computes η^{n+1}; the last one only for the velocity at T
        d2 = second_difference(eta, dx)
        rhs = 2.0 * eta[1:-1] - eta_prev[1:-1] + dt**2 * d2 - s * dx**2 * d2
        # the ends are fixed, so their part of −αΔt D²η^{n+1} is known
        rhs[0] += s * h_left
        rhs[-1] += s * h_right
        new = np.empty_like(eta)
        new[0], new[-1] = h_left, h_right
        new[1:-1] = solve_banded((1, 1), bands, rhs, check_finite=False) if alpha > 0 else rhs
        new[1:-1] = np.maximum(new[1:-1], psi[1:-1])
        if alpha > 0 and not nodal:
            _projected_gauss_seidel(new, rhs, s, psi)
        if k < len(steps) and steps[k] == n:
            vel_out[k] = (new - eta_prev) / (2.0 * dt)
            k += 1
        eta_prev, eta = eta, new
        if k < len(steps) and steps[k] == n + 1:
            eta_out[k] = eta
    return dt * np.asarray(steps, dtype=float), eta_out, vel_out


def _projected_gauss_seidel(eta, rhs, s, psi, rtol=1e-15, max_sweeps=100_000):
    """Solve (1 + 2s) η_j − s(η_{j−1} + η_{j+1}) ≥ rhs_j, η_j ≥ ψ_j, complementary, in place on the interior
    (ends fixed): red-black sweeps η_j ← max(ψ_j, (rhs_j + s(η_{j−1} + η_{j+1}))/(1 + 2s)) until no node moves
    by more than `rtol` of the largest |η|."""
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
