"""Tests of the exact oracles (exact.py, conftest.sine_mode) and of the plain-NumPy finite-difference reference
(reference.py)."""

import numpy as np
import pytest
from conftest import sine_mode

from stringcontact.fem.compat import trapezoid
from stringcontact.verification.exact import flat_landing, flat_landing_energy_loss, flat_landing_time
from stringcontact.verification.reference import fd_solve

H, V, LENGTH = 0.2, 1.0, 1.0


def energy(eta, velocity, x):
    r"""Kinetic plus elastic energy :math:`\tfrac12\int v^2 + \tfrac12\int\eta_x^2` of nodal values on grid ``x``.

    The elastic part is exact for the piecewise-linear interpolant of ``eta``.
    """
    kinetic = 0.5 * trapezoid(velocity**2, x, axis=-1)
    elastic = 0.5 * np.sum(np.diff(eta, axis=-1) ** 2 / np.diff(x), axis=-1)
    return kinetic + elastic


def l2_norm(f, dx):
    return np.sqrt(dx * np.sum(f**2, axis=-1))


# --- sine_mode ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("alpha", [0.0, 0.1, 2.0 / (2 * np.pi), 1.0], ids=["undamped", "underdamped", "critical", "overdamped"])
def test_sine_mode_amplitude_solves_its_ode_and_initial_conditions(alpha):
    k, length, a0, a1, h = 2, 1.0, 0.3, -0.7, 0.5
    kappa = k * np.pi / length
    x_peak = np.array([length / (2 * k)])  # sin(kappa x) = 1, so eta - h = a(t) and velocity = a'(t)
    t = np.linspace(0.0, 2.0, 20001)
    dt = t[1] - t[0]
    eta, velocity = sine_mode(t, x_peak, k=k, a0=a0, a1=a1, alpha=alpha, length=length, h=h)
    a, da = eta[:, 0] - h, velocity[:, 0]

    assert a[0] == pytest.approx(a0, abs=1e-14)
    assert da[0] == pytest.approx(a1, abs=1e-14)
    # The returned velocity is the time derivative of the returned displacement ...
    np.testing.assert_allclose(np.gradient(a, dt)[1:-1], da[1:-1], atol=1e-6)
    # ... and a'' + alpha kappa^2 a' + kappa^2 a = 0, with a'' from central differences of a.
    d2a = (a[2:] - 2 * a[1:-1] + a[:-2]) / dt**2
    residual = d2a + alpha * kappa**2 * da[1:-1] + kappa**2 * a[1:-1]
    assert np.max(np.abs(residual)) < 1e-5 * kappa**2


def test_sine_mode_shapes():
    x = np.linspace(0.0, 1.0, 7)
    eta, velocity = sine_mode(0.3, x, k=1, a0=0.1, a1=0.0, alpha=0.1, length=1.0, h=2.0)
    assert eta.shape == velocity.shape == (7,)
    eta, velocity = sine_mode(np.array([0.0, 0.3]), x, k=1, a0=0.1, a1=0.0, alpha=0.1, length=1.0, h=2.0)
    assert eta.shape == velocity.shape == (2, 7)
    np.testing.assert_allclose(eta[:, [0, -1]], 2.0, atol=1e-15)


# --- flat_landing ------------------------------------------------------------------------------------------


def test_flat_landing_rejects_data_without_flat_middle():
    with pytest.raises(ValueError, match="V\\*length/2"):
        flat_landing(0.1, np.linspace(0, 1, 5), h=0.6, V=1.0, length=1.0)


def test_flat_landing_is_continuous_at_landing_and_lands_flat():
    t_star = flat_landing_time(H, V)
    x = np.linspace(0.0, LENGTH, 1001)
    eta_at, _ = flat_landing(t_star, x, h=H, V=V, length=LENGTH)  # pre-landing formula
    eta_after, velocity_after = flat_landing(np.nextafter(t_star, 1.0), x, h=H, V=V, length=LENGTH)
    np.testing.assert_allclose(eta_after, eta_at, atol=1e-12)

    middle = (x >= t_star) & (x <= LENGTH - t_star)
    np.testing.assert_allclose(eta_at[middle], 0.0, atol=1e-14)
    assert np.all(eta_at[~middle] > 0.0)
    # Inelastic landing: nothing moves right after t*, apart from the two kink points themselves.
    away_from_kinks = np.abs(np.abs(x - LENGTH / 2) - (LENGTH / 2 - t_star)) > 1e-9
    np.testing.assert_allclose(velocity_after[away_from_kinks], 0.0, atol=1e-14)


def test_flat_landing_never_penetrates_and_keeps_its_ends():
    t = np.linspace(0.0, 3.0, 601)
    x = np.linspace(0.0, LENGTH, 401)
    eta, _ = flat_landing(t, x, h=H, V=V, length=LENGTH)
    assert eta.min() >= -1e-14
    np.testing.assert_allclose(eta[:, [0, -1]], H, atol=1e-14)
    # The string does move after landing, so the non-penetration check is not vacuous.
    assert eta[t > 1.0].max() > 1.5 * H


@pytest.mark.parametrize("t", [0.1, 0.35, 0.9, 1.7, 2.6])
def test_flat_landing_velocity_is_time_derivative(t):
    x = np.linspace(0.0, LENGTH, 997)  # deliberately not aligned with the kinks
    delta = 1e-7
    eta_plus, _ = flat_landing(t + delta, x, h=H, V=V, length=LENGTH)
    eta_minus, _ = flat_landing(t - delta, x, h=H, V=V, length=LENGTH)
    _, velocity = flat_landing(t, x, h=H, V=V, length=LENGTH)
    mismatch = np.abs((eta_plus - eta_minus) / (2 * delta) - velocity) > 1e-5
    # Only points within delta of a kink may disagree.
    assert mismatch.sum() <= 4
    assert np.abs(velocity).max() > 0.4 * V


def test_flat_landing_energy_drop_equals_lost_kinetic_energy():
    t_star = flat_landing_time(H, V)
    x = np.linspace(0.0, LENGTH, 20001)
    before = energy(*flat_landing(t_star, x, h=H, V=V, length=LENGTH), x)
    after = energy(*flat_landing(np.nextafter(t_star, 1.0), x, h=H, V=V, length=LENGTH), x)
    initial = energy(*flat_landing(0.0, x, h=H, V=V, length=LENGTH), x)

    assert flat_landing_energy_loss(H, V, LENGTH) == pytest.approx(0.5 * V**2 * (LENGTH - 2 * H / V))
    assert before == pytest.approx(0.5 * V**2 * LENGTH, rel=1e-3)  # conserved up to landing
    assert initial - after == pytest.approx(flat_landing_energy_loss(H, V, LENGTH), rel=1e-3)
    assert before - after == pytest.approx(flat_landing_energy_loss(H, V, LENGTH), rel=1e-3)


def test_flat_landing_energy_is_conserved_after_landing():
    t_star = flat_landing_time(H, V)
    x = np.linspace(0.0, LENGTH, 20001)
    t = np.linspace(t_star + 1e-3, 3.0, 37)
    energies = energy(*flat_landing(t, x, h=H, V=V, length=LENGTH), x)
    energy_after_landing = 0.5 * V**2 * LENGTH - flat_landing_energy_loss(H, V, LENGTH)
    np.testing.assert_allclose(energies, energy_after_landing, rtol=3e-3)


# --- fd_solve ----------------------------------------------------------------------------------------------


def test_fd_solve_output_rows_and_start_up_convention():
    x = np.linspace(0.0, 1.0, 11)
    t, eta, velocity = fd_solve(1 + x, -np.ones_like(x), length=1.0, T=1.0, nt=10, alpha=0.1, eps=np.inf,
                                h_left=0.5, h_right=0.7, store_every=4)
    np.testing.assert_allclose(t, [0.0, 0.4, 0.8, 1.0])
    assert eta.shape == velocity.shape == (4, 11)
    assert (eta[0, 0], eta[0, -1]) == (0.5, 0.7)
    np.testing.assert_array_equal(eta[0, 1:-1], 1 + x[1:-1])
    np.testing.assert_allclose(velocity[0], np.r_[0.0, -np.ones(9), 0.0], atol=1e-12)
    np.testing.assert_array_equal(eta[:, 0], 0.5)
    np.testing.assert_array_equal(eta[:, -1], 0.7)


def test_fd_solve_keeps_a_straight_string_at_rest():
    x = np.linspace(0.0, 2.0, 41)
    line = 0.3 + (1.1 - 0.3) * x / 2.0
    _, eta, velocity = fd_solve(line, np.zeros_like(x), length=2.0, T=1.0, nt=25, alpha=0.2, eps=1e-3,
                                h_left=0.3, h_right=1.1, store_every=5)
    np.testing.assert_allclose(eta, np.broadcast_to(line, eta.shape), atol=1e-13)
    np.testing.assert_allclose(velocity, 0.0, atol=1e-12)


@pytest.mark.parametrize("penalty", ["explicit", "semi-implicit"])
def test_fd_solve_satisfies_the_paper_scheme_pointwise(penalty):
    """Residual of the Section 6 formula, evaluated directly on the output, with contact active."""
    N, nt, length, T, alpha, eps = 40, 30, 1.0, 0.3, 0.05, 0.02
    x = np.linspace(0.0, length, N + 1)
    dx, dt = length / N, T / nt
    _, eta, _ = fd_solve(0.05 + 0.2 * np.sin(3 * np.pi * x), -1.0 - x, length=length, T=T, nt=nt,
                         alpha=alpha, eps=eps, h_left=0.05, h_right=0.25, penalty=penalty)
    eta_new, eta_now, eta_old = eta[2:], eta[1:-1], eta[:-2]  # steps n+1, n, n-1 for n = 1..nt-1

    def d2(e):
        return (e[:, 2:] - 2 * e[:, 1:-1] + e[:, :-2]) / dx**2

    inner = slice(1, -1)
    v_now = (eta_now[:, inner] - eta_old[:, inner]) / dt
    if penalty == "explicit":
        force = (eta_now[:, inner] < 0) * np.maximum(-v_now, 0.0) / eps
    else:
        active = (eta_now[:, inner] < 0) & (v_now < 0)
        force = -active.astype(float) * (eta_new[:, inner] - eta_now[:, inner]) / dt / eps
    residual = ((eta_new[:, inner] - 2 * eta_now[:, inner] + eta_old[:, inner]) / dt**2
                - alpha / dt * (d2(eta_new) - d2(eta_now)) - d2(eta_new) - force)
    assert np.count_nonzero(force) > 20  # contact really happens
    assert np.max(np.abs(residual)) < 1e-8 * np.max(np.abs(force))


@pytest.mark.parametrize("alpha", [0.0, 0.5])
def test_fd_solve_converges_at_first_order_to_sine_mode_without_contact(alpha):
    h, a0, T = 2.0, 0.1, 1.0
    errors = []
    for N in (100, 200):
        x = np.linspace(0.0, 1.0, N + 1)
        t, eta, velocity = fd_solve(h + a0 * np.sin(np.pi * x), np.zeros_like(x), length=1.0, T=T, nt=N,
                                    alpha=alpha, eps=1e30, h_left=h, h_right=h, store_every=N // 4)
        exact, _ = sine_mode(t, x, k=1, a0=a0, a1=0.0, alpha=alpha, length=1.0, h=h)
        errors.append(np.max(np.abs(eta - exact)))
    assert errors[1] < 0.05 * a0
    assert errors[0] / errors[1] >= 1.6


def solve_flat_landing(N, *, penalty, eps, T=0.6):
    x = np.linspace(0.0, LENGTH, N + 1)
    t, eta, velocity = fd_solve(np.full_like(x, H), np.full_like(x, -V), length=LENGTH, T=T, nt=N,
                                alpha=0.0, eps=eps, h_left=H, h_right=H, penalty=penalty)
    return x, t, eta, velocity


def test_fd_solve_semi_implicit_converges_to_flat_landing():
    errors = []
    for N in (200, 400, 800):
        x, t, eta, _ = solve_flat_landing(N, penalty="semi-implicit", eps=1e-8)
        exact, _ = flat_landing(t[-1], x, h=H, V=V, length=LENGTH)
        errors.append(l2_norm(eta[-1] - exact, LENGTH / N))
        # The stiff penalty lets a node overshoot by at most one step of the incoming velocity.
        assert eta.min() >= -V * (t[1] - t[0])
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < 0.03 * H
    assert eta.min() >= -1e-3


def test_fd_solve_explicit_penalty_stops_the_middle_without_bounce():
    N, T = 400, 0.6
    x, t, eta, velocity = solve_flat_landing(N, penalty="explicit", eps=(T / N) / 0.5, T=T)  # dt/eps = 0.5
    assert np.all(np.isfinite(eta))
    assert np.abs(eta).max() <= 2 * H * 1.05  # the exact solution stays in [0, 2h]
    assert eta.min() >= -2 * V * (t[1] - t[0])

    middle = N // 2
    landing = np.argmax(eta[:, middle] < 0.0)
    after = velocity[landing + 1: landing + 20, middle]
    # v^{n+1} = (1 - dt/eps) v^n on the flat middle: monotone decay, never upward.
    assert np.all(after <= 0.0)
    assert np.all(np.diff(np.abs(after)) <= 0.0)
    assert np.abs(after[-1]) < 1e-4 * V
