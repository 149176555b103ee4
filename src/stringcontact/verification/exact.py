"""The exact flat landing, the studies' oracle: `flat_landing` returns ``(eta, velocity)``, of shape ``(len(t), len(x))``
for an array ``t``, ``(len(x),)`` for a scalar one."""

import numpy as np


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
    tt, xx = np.broadcast_arrays(np.atleast_1d(np.asarray(t, dtype=float))[:, None], np.asarray(x, dtype=float)[None, :])
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
    velocity = np.where(before, np.where(distance_to_end > tt, -V, 0.0), vel_after)
    return (eta[0], velocity[0]) if np.ndim(t) == 0 else (eta, velocity)  # rows = times; one row for a scalar t
