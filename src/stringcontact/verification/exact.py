"""Exact solutions used as test oracles: `sine_mode` and `flat_landing` return ``(eta, velocity)``, of shape
``(len(t), len(x))`` for an array ``t``, ``(len(x),)`` for a scalar one."""

import numpy as np


def _on_grid(t, x):
    """Broadcast ``t`` against ``x`` as (rows = times, columns = points); remember whether t was scalar."""
    return np.atleast_1d(np.asarray(t, dtype=float))[:, None], np.asarray(x, dtype=float)[None, :], np.ndim(t) == 0


def _finish(eta, velocity, scalar):
    """The rows for an array t, the one row for a scalar t."""
    return (eta[0], velocity[0]) if scalar else (eta, velocity)


def damped_oscillator(t, *, a0, a1, damping, stiffness):
    r"""``(a, a')`` of :math:`a'' + 2\beta a' + \kappa^2 a = 0`, :math:`a(0) = a_0`, :math:`a'(0) = a_1`
    (``damping`` :math:`2\beta`, ``stiffness`` :math:`\kappa^2`): :math:`a = a_0 C + (a_1 + \beta a_0) S`,
    :math:`a' = a_1 C - (\kappa^2 a_0 + \beta a_1) S`, :math:`C = e^{-\beta t}\cos\omega t`,
    :math:`S = e^{-\beta t}\sin(\omega t)/\omega`, :math:`\omega^2 = \kappa^2 - \beta^2` (cosh, sinh below 0)."""
    t = np.asarray(t, dtype=float)
    beta = 0.5 * damping
    omega2 = stiffness - beta**2
    if omega2 > 0.0:
        omega = np.sqrt(omega2)
        C = np.exp(-beta * t) * np.cos(omega * t)
        S = np.exp(-beta * t) * t * np.sinc(omega * t / np.pi)  # sin(ωt)/ω via sinc: accurate as ω → 0
    elif omega2 == 0.0:
        C = np.exp(-beta * t)
        S = t * C
    else:
        gamma = np.sqrt(-omega2)
        # with the slow rate γ − β = −κ²/(β + γ) and e^{−2γt} ≤ 1 nothing overflows or cancels for small γ
        slow = np.exp(-stiffness / (beta + gamma) * t)
        fast = np.exp(-2.0 * gamma * t)
        C = 0.5 * slow * (1.0 + fast)
        z = 2.0 * gamma * t  # S = slow t (1 − e^{−z})/z, that quotient 1 at z = 0
        S = slow * t * np.where(z == 0.0, 1.0, -np.expm1(-z) / np.where(z == 0.0, 1.0, z))
    a = a0 * C + (a1 + beta * a0) * S
    da = a1 * C - (stiffness * a0 + beta * a1) * S
    return a, da


def sine_mode(t, x, *, k, a0, a1, alpha, length, h):
    r"""No-contact mode :math:`\eta = h + a(t)\sin(\kappa x)`, :math:`\kappa = k\pi/l`, of :math:`\eta_{tt} -
    \alpha\eta_{txx} - \eta_{xx} = 0`: :math:`a'' + \alpha\kappa^2 a' + \kappa^2 a = 0`, :math:`a(0) = a_0`,
    :math:`a'(0) = a_1`."""
    if alpha < 0:
        raise ValueError(f"alpha must be >= 0, got {alpha}")
    kappa = k * np.pi / length
    tt, xx, scalar = _on_grid(t, x)
    a, da = damped_oscillator(tt, a0=a0, a1=a1, damping=alpha * kappa**2, stiffness=kappa**2)
    shape = np.sin(kappa * xx)
    return _finish(h + a * shape, da * shape, scalar)


def flat_landing_time(h, V):
    r"""Landing time :math:`t^* = h/V` of the flat middle part of the string."""
    return h / V


def flat_landing_energy_loss(h, V, length):
    r"""Kinetic energy destroyed at landing, :math:`\tfrac12 V^2 (l - 2t^*)`."""
    return 0.5 * V**2 * (length - 2.0 * flat_landing_time(h, V))


def _mirrored(s, length):
    """(m, upper): s folded into [0, l] by the odd 2l-periodic extension, and where it was folded (f(s) = −f(2l − s))."""
    r = np.mod(s, 2.0 * length)
    return np.where(r > length, 2.0 * length - r, r), r > length


def _landed_profile(s, *, h, V, length):
    r"""The odd, 2l-periodic extension W of :math:`w = \max(h - V\min(x, l-x), 0) - h` and W' (kinks: the mean)."""
    t_star = flat_landing_time(h, V)
    m, upper = _mirrored(s, length)  # W' is even: W'(s) = w'(2l − s) on (l, 2l)
    w = np.maximum(h - V * np.minimum(m, length - m), 0.0) - h
    dw = -V * np.heaviside(t_star - m, 0.5) + V * np.heaviside(m - (length - t_star), 0.5)
    return np.where(upper, -w, w), dw


def flat_landing_rebound_end(h, V, length):
    r"""End :math:`l + 3t^*` of the window after the landing at :math:`t^*` in which the string, rebounding with
    any restitution :math:`e \in [0, 1]`, stays above the obstacle (see :func:`flat_landing`)."""
    return length + 3.0 * flat_landing_time(h, V)


def _rebound_potential(s, *, h, V, length):
    r"""The odd, 2l-periodic extension U of :math:`V\,1_{(t^*, l - t^*)}` (jumps: the mean) and Φ = ∫_0^s U (even)."""
    t_star = flat_landing_time(h, V)
    m, upper = _mirrored(s, length)
    phi = V * np.clip(m - t_star, 0.0, length - 2.0 * t_star)
    u = V * (np.heaviside(m - t_star, 0.5) - np.heaviside(m - (length - t_star), 0.5))
    return np.where(upper, -u, u), phi


def flat_landing(t, x, *, h=0.2, V=1.0, length=1.0, restitution=0.0):
    r"""Exact inelastic solution for α = 0, ends at h, η₀ = h, v₀ = −V (h < Vl/2): until t* = h/V (d'Alembert)
    η = h − V min(x, l − x, t); then the flat middle [t*, l − t*] stops on y = 0 and, τ = t − t*,
    :math:`\eta = h + \tfrac12[W(x - \tau) + W(x + \tau)]` (`_landed_profile`; |W| ≤ h: no penetration again).
    A ``restitution`` e ∈ (0, 1] rebounds the middle at +eV, adding :math:`\tfrac{e}{2}[\Phi(x + \tau) - \Phi(x -
    \tau)]` (`_rebound_potential`), valid until it lands again: times after l + 3t* are refused."""
    if not (h > 0 and V > 0 and length > 0):
        raise ValueError(f"need h > 0, V > 0, length > 0, got h={h}, V={V}, length={length}")
    if not h < V * length / 2:
        raise ValueError(f"the flat middle must exist at landing: need h < V*length/2, got h={h}, "
                         f"V*length/2={V * length / 2}")
    if not 0.0 <= restitution <= 1.0:
        raise ValueError(f"restitution must be in [0, 1], got {restitution}")
    t_star = flat_landing_time(h, V)
    tt, xx, scalar = _on_grid(t, x)
    tt, xx = np.broadcast_arrays(tt, xx)
    if restitution > 0 and np.any(tt > flat_landing_rebound_end(h, V, length)):
        raise ValueError(f"with restitution {restitution} the exact solution is known for t <= l + 3 h/V = "
                         f"{flat_landing_rebound_end(h, V, length):.6g} only (the string lands again then)")

    distance_to_end = np.minimum(xx, length - xx)
    tau = np.maximum(tt - t_star, 0.0)
    W_minus, dW_minus = _landed_profile(xx - tau, h=h, V=V, length=length)
    W_plus, dW_plus = _landed_profile(xx + tau, h=h, V=V, length=length)
    eta_after = h + 0.5 * (W_minus + W_plus)
    vel_after = 0.5 * (-dW_minus + dW_plus)
    if restitution > 0:
        U_minus, phi_minus = _rebound_potential(xx - tau, h=h, V=V, length=length)
        U_plus, phi_plus = _rebound_potential(xx + tau, h=h, V=V, length=length)
        eta_after = eta_after + 0.5 * restitution * (phi_plus - phi_minus)
        vel_after = vel_after + 0.5 * restitution * (U_plus + U_minus)

    before = tt <= t_star
    eta = np.where(before, h - V * np.minimum(distance_to_end, tt), eta_after)
    return _finish(eta, np.where(before, np.where(distance_to_end > tt, -V, 0.0), vel_after), scalar)
