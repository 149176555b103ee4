"""The flat landing's exact solution with a restitution e (verification.exact.flat_landing): d'Alembert from the
rebound state, inside the window t <= l + 3 h/V in which the free motion stays above the obstacle."""

import numpy as np
import pytest

from stringcontact.verification import exact

H, V, L = 0.2, 1.0, 1.0
X = np.linspace(0.0, L, 801)
T_STAR = H / V
END = exact.flat_landing_rebound_end(H, V, L)


def _eta(t, x, e):
    return exact.flat_landing(t, x, h=H, V=V, length=L, restitution=e)[0]


def test_e0_is_the_inelastic_solution():
    t = np.linspace(0.0, 2.5, 51)
    for a, b in zip(exact.flat_landing(t, X), exact.flat_landing(t, X, restitution=0.0)):
        assert np.array_equal(a, b)


@pytest.mark.parametrize("e", [0.25, 0.5, 1.0])
def test_rebound_state_and_wave_equation(e):
    middle = (X > T_STAR + 0.01) & (X < L - T_STAR - 0.01)
    eta, v = exact.flat_landing(T_STAR + 0.005, X, h=H, V=V, length=L, restitution=e)
    assert np.allclose(v[middle], e * V) and np.allclose(eta[middle], e * V * 0.005)
    assert np.allclose(_eta(np.linspace(0, END, 7), np.array([0.0, L]), e), H, rtol=0, atol=1e-15)  # the ends
    s, inner = 0.04, X[(X > 0.05) & (X < 0.95)]
    for t in (0.3, 0.8, 1.4):  # d'Alembert's parallelogram rule: a solution of η_tt = η_xx, to round-off
        d = _eta(t, inner + s, e) + _eta(t, inner - s, e) - _eta(t - s, inner, e) - _eta(t + s, inner, e)
        assert np.max(np.abs(d)) < 1e-14
    t = np.array([0.7, 0.7 + 1e-7])  # η_t is the returned velocity
    (a, b), (va, _) = exact.flat_landing(t, X, h=H, V=V, length=L, restitution=e)
    assert np.median(np.abs((b - a) / 1e-7 - va)) < 1e-6


@pytest.mark.parametrize("e", [0.25, 0.5, 1.0])
def test_stays_above_the_obstacle_in_the_window(e):
    t = np.linspace(T_STAR + 1e-3, END - 1e-3, 400)
    assert np.min(_eta(t, X[1:-1], e)) > 0
    if e == 1.0:  # the window is sharp: at e = 1 the middle lands again at its end
        assert _eta(END, np.array([0.5]), e)[0] == pytest.approx(0.0, abs=1e-12)


def test_refuses_times_after_the_window_and_bad_e():
    with pytest.raises(ValueError, match="known for t <= l"):
        exact.flat_landing(END + 0.01, X, restitution=0.5)
    with pytest.raises(ValueError, match=r"restitution must be in \[0, 1\]"):
        exact.flat_landing(0.5, X, restitution=1.5)
