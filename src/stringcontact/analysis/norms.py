"""The studies' errors ``err_eta`` (L∞(0,T;L²) of η), ``err_vel`` (L² of η_t at T) and ``err_contact`` (the contact
sets' symmetric difference in space-time), at the run's nodes and times (docs/explanation/study.md)."""

from __future__ import annotations

import numpy as np

from .problems import Run

#: Contact sets in the errors are {η ≤ δ}, δ = CONTACT_HEIGHT · Δx · max|η|/l, the height a grid resolves (with δ = 0
#: a string resting on the obstacle at ±round-off is noise).
CONTACT_HEIGHT = 1.0


def l2_norm(x: np.ndarray, f: np.ndarray) -> np.ndarray:
    """‖f‖_{L²(0,l)} of nodal values f (rows = times), trapezoidal."""
    from ..fem import compat

    return np.sqrt(compat.trapezoid(f**2, x, axis=-1))


def to_nodes(x_from: np.ndarray, values: np.ndarray, x_to: np.ndarray) -> np.ndarray:
    """P1 interpolation of rows of nodal values onto other nodes."""
    values = np.atleast_2d(values)
    return np.array([np.interp(x_to, x_from, row) for row in values])


def common_rows(t_run: np.ndarray, t_ref: np.ndarray) -> np.ndarray:
    """Indices into t_ref of the run's stored times (they must be among the reference's)."""
    idx = np.searchsorted(t_ref, t_run - 1e-12 * max(1.0, t_ref[-1]))
    idx = np.minimum(idx, t_ref.size - 1)
    if not np.allclose(t_ref[idx], t_run, rtol=0, atol=1e-9 * max(1.0, t_ref[-1])):
        raise ValueError("the run's stored times are not among the reference's: use matching rows")
    return idx


def errors_against_exact(run: Run, exact) -> dict:
    """The three errors of `run` against `exact(t, x) -> (eta, velocity)`."""
    return _errors(run, exact(run.t, run.x)[0], exact(run.t[-1], run.x)[1])


def errors_against_reference(run: Run, ref: Run) -> dict:
    """The three errors of `run` against a finer run `ref` (interpolated to the run's nodes and times)."""
    eta = to_nodes(ref.x, ref.eta[common_rows(run.t, ref.t)], run.x)
    return _errors(run, eta, to_nodes(ref.x, ref.velocity_T, run.x)[0])


def _errors(run: Run, eta: np.ndarray, vel_T: np.ndarray) -> dict:
    from ..fem import compat

    length = run.x[-1] - run.x[0]
    delta = CONTACT_HEIGHT * (length / run.nx) * float(np.max(np.abs(run.eta[0]))) / length
    sym_diff = ((run.eta <= delta) != (eta <= delta)).astype(float)
    measure = compat.trapezoid(sym_diff, run.x, axis=1)
    return {
        "err_eta": float(np.max(l2_norm(run.x, run.eta - eta))),
        "err_vel": float(l2_norm(run.x, run.velocity_T - vel_T)),
        "err_contact": float(compat.trapezoid(measure, run.t)) if run.t.size > 1 else float(measure[0])}
