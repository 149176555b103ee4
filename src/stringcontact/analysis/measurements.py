"""The numbers the theorem checks judge, from a `Result` of every step, in the scheme's own terms (`momentum_terms`)."""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass

import numpy as np
from scipy import ndimage


def require_every_step(result) -> None:
    """A ValueError unless `result` stores every time step from step 0 on."""
    steps = np.asarray(result.steps)
    if steps.size < 2 or np.any(np.diff(steps) != 1) or steps[0] != 0:
        raise ValueError("the theorem checks need every time step stored: run simulate(scene, "
                         "storage=Storage(max_rows=scene.nt))")


def nodal_weights(result) -> np.ndarray:
    """Lumped P1 mass m_j of the nodes (Δx/2 at the ends) on the result's grid."""
    dx = np.diff(result.x, prepend=result.x[0], append=result.x[-1])
    return 0.5 * (dx[:-1] + dx[1:])


def impulse(result) -> np.ndarray:
    """Nodal contact impulse Δt m_j F^n_j of every step, shape (rows, nodes); row 0 is zero."""
    return result.scene.dt * momentum_terms(result).force * nodal_weights(result)[None, :]


def interior(result) -> np.ndarray:
    """True at every node but the two ends."""
    return np.isin(np.arange(result.x.size), (0, result.x.size - 1), invert=True)


def free_boundary(contact: np.ndarray, neighbours=ndimage.generate_binary_structure(2, 1)) -> np.ndarray:
    """∂{η ≤ 0} on the (step, node) grid: the points whose contact flag differs from one of their `neighbours`."""
    c = np.asarray(contact, dtype=bool)
    return np.where(c, ~ndimage.binary_erosion(c, neighbours, border_value=1), ndimage.binary_dilation(c, neighbours))


def distance_to_free_boundary(contact: np.ndarray) -> np.ndarray:
    """Chessboard distance (cells or steps) of each grid point to ∂{η ≤ 0} (a large one without a free boundary)."""
    b = free_boundary(contact)
    if not b.any():
        return np.full(b.shape, np.iinfo(np.int32).max, dtype=np.int64)
    return ndimage.distance_transform_cdt(~b, metric="chessboard").astype(np.int64)


def _previous(rows: np.ndarray) -> np.ndarray:
    """Row n holds row n − 1 (row 0 itself)."""
    return np.concatenate([rows[:1], rows[:-1]])


@dataclass(frozen=True)
class Momentum:
    """A step as the momentum equation m_j F^n_j = m_j (q^n_j − q^{n−1}_j)/Δt − (S^n_{j+½} − S^n_{j−½}),
    S = (η_S)_x + α (q_S)_x, over (rows, nodes): η_S at t_n (`paper`), t_{n−1} (`projection`), their mean (`newmark`);
    w, the velocity the ledger books the contact work with; F, the force of the step t_{n−1} → t_n."""

    q: np.ndarray
    eta_s: np.ndarray
    q_s: np.ndarray
    w: np.ndarray
    force: np.ndarray
    obstacle_w: np.ndarray | float = 0.0  # a moving obstacle's rate paired with w (w − obstacle_w: the gap's rate)
    obstacle_q: np.ndarray | float = 0.0  # and paired with q (q − obstacle_q: the gap's rate in the step)


def momentum_terms(result) -> Momentum:
    """The terms of `result.scheme`'s discrete momentum equation (`Momentum`)."""
    require_every_step(result)
    eta, v, F, scheme = result.eta, result.velocity, result.contact_force, result.scheme
    psi = obstacle_rows(result)
    backward = 0.0 if psi is None else np.diff(psi[:-1], axis=0) / result.scene.dt  # (ψ^n − ψ^{n−1})/Δt, row n
    if scheme == "projection":
        q = np.concatenate([v[:1], np.diff(eta, axis=0) / result.scene.dt])  # the half-step velocities
        w_psi = 0.0 if psi is None else 0.5 * (backward + _previous(backward))
        return Momentum(q, _previous(eta), q, 0.5 * (q + _previous(q)), F, w_psi, backward)
    if scheme == "newmark":
        mean = 0.5 * (v + _previous(v))
        return Momentum(v, 0.5 * (eta + _previous(eta)), mean, mean, F, backward, obstacle_velocity(result))
    if result.penalty == "explicit":  # row n holds F(η^n, v^n), which the step t_n → t_{n+1} applies
        F = np.concatenate([np.zeros_like(F[:1]), F[:-1]])
    return Momentum(v, eta, v, v, F, backward, backward)


#: `obstacle_rows` of each result, computed once: every check reads it (67 ms a time on the piston's 251 rows).
_OBSTACLE_ROWS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def obstacle_rows(result) -> np.ndarray | None:
    """A moving obstacle ψ(x, t) at t_0 − Δt, the stored times and t_N + Δt, shape (rows + 2, nodes); None at rest."""
    scene = result.scene
    if not getattr(scene, "obstacle_moves", False):
        return None
    rows = _OBSTACLE_ROWS.get(result)
    if rows is None or rows.shape != (result.t.size + 2, result.x.shape[0]):
        times = np.concatenate([[result.t[0] - scene.dt], result.t, [result.t[-1] + scene.dt]])
        rows = np.array([scene.obstacle_values(result.x, float(t)) for t in times], dtype=float)
        _OBSTACLE_ROWS[result] = rows
    return rows


def obstacle_velocity(result) -> np.ndarray | float:
    """ψ_t paired with the stored velocity (0 at rest): backward for `paper`, centred for `projection`, `newmark`."""
    psi = obstacle_rows(result)
    if psi is None:
        return 0.0
    if result.scheme in ("projection", "newmark"):
        return (psi[2:] - psi[:-2]) / (2 * result.scene.dt)
    return np.diff(psi[:-1], axis=0) / result.scene.dt


def relative_velocity(result) -> np.ndarray:
    """v − ψ_t at every stored row and node: the string's velocity relative to the obstacle."""
    return result.velocity - obstacle_velocity(result)


def first_contact_rows(result) -> np.ndarray:
    """Row of each node's first contact (η ≤ 0); −1 if never, 0 if in contact from the start."""
    c = np.asarray(result.contact, dtype=bool)
    first = np.argmax(c, axis=0)
    return np.where(c.any(axis=0), first, -1)


def _runs(mask: np.ndarray, min_nodes: int = 1) -> list[tuple[int, int]]:
    """Maximal runs [a, b] (inclusive node indices) of at least `min_nodes` True in a 1-D mask."""
    from ..plot.charts import contact_components

    return [(int(a), int(b)) for a, b in contact_components(np.arange(np.size(mask)), mask, min_nodes)]


def band_width(result, delta: float) -> int:
    """Half-width in cells (at least 1) of the band of physical half-width `delta` around the fronts."""
    return max(1, int(round(delta / float(np.diff(result.x).mean()))))


def force_sign(result) -> dict:
    """min F, max F, min F (η_t − ψ_t)⁻, and the negative share of the ledger's dissipation −F^n (w^n − ψ_t)."""
    terms = momentum_terms(result)
    F = result.contact_force
    D = -terms.force[1:] * (terms.w - terms.obstacle_w)[1:]
    positive = D[D > 0].sum()
    return {"min_force": float(F.min()), "max_force": float(F.max()),
            "paper_dissipation_min": float((F * np.maximum(-relative_velocity(result), 0.0)).min()),
            "negative_dissipation_share": float(abs(D[D < 0].sum()) / positive) if positive > 0 else 0.0}  # never -0


def support_concentration(result, ks=(1, 2, 4), lengths=()) -> dict:
    """Share of the total impulse within k cells/steps of ∂{η ≤ 0}, for each k and each physical length in `lengths`."""
    I = impulse(result)
    total = I.sum()
    d = distance_to_free_boundary(result.contact)
    step = max(float(np.diff(result.x).max()), result.scene.dt)
    cells = {f"within_{k}": k for k in ks}
    cells |= {f"within_length_{L:g}": max(0, int(math.floor(L / step + 1e-9))) for L in lengths}  # in cells/steps
    out = {"support_measure": float((I > 0).sum() * result.scene.dt * float(np.diff(result.x).mean()))}
    return out | {name: float(I[d <= k].sum() / total) if total > 0 else math.nan for name, k in cells.items()}


def upward_impulse(result) -> dict:
    """Share of the impulse where the string moves up (off a moving obstacle): pointwise, and on the 3×3
    neighbourhood of rows and nodes (a discrete int{η_t ≥ 0}, the set of (A3))."""
    I = impulse(result)
    total = I.sum()
    if obstacle_rows(result) is None:
        up = result.velocity >= 0  # row 0 is v0, which sets the force of the first step
    else:  # q − ψ_t > 0 beyond the quotients' round-off: the force that carries the string acts where it is 0
        terms = momentum_terms(result)
        tol = 1e-9 * max(float(np.max(np.abs(terms.q))), float(np.max(np.abs(terms.obstacle_q))))
        up = terms.q - terms.obstacle_q > tol
    nbhd = ndimage.binary_erosion(up, structure=np.ones((3, 3), dtype=bool), border_value=1)
    share = (lambda mask: float(I[mask].sum() / total)) if total > 0 else (lambda mask: math.nan)
    return {"pointwise": share(up), "neighbourhood": share(nbhd)}


def velocity_after_contact(result, delay: float) -> dict:
    """Σ|v(t_0 + delay)| / Σ|v(t_0)| (v − ψ_t) over the nodes touching down at t_0 > 0 and in contact until then,
    and the 95th percentile of the nodes' ratios (those with 1 % of the largest impact speed)."""
    require_every_step(result)
    first = first_contact_rows(result)
    lag = max(1, int(round(delay / result.scene.dt)))
    nodes = np.flatnonzero(interior(result) & (first >= 1) & (first + lag < result.t.size))
    c = np.asarray(result.contact, dtype=bool)
    stays = np.array([c[first[j]:first[j] + lag + 1, j].all() for j in nodes], dtype=bool)
    kept = nodes[stays] if nodes.size else nodes
    if kept.size == 0:
        return {"ratio": math.nan, "p95": math.nan, "nodes": 0, "left_early": int(nodes.size)}
    v = relative_velocity(result)
    impact = np.abs(v[first[kept], kept])
    after = np.abs(v[first[kept] + lag, kept])
    big = impact >= 0.01 * impact.max()
    ratios = after[big] / impact[big]
    return {"ratio": float(after.sum() / impact.sum()), "p95": float(np.percentile(ratios, 95)) if ratios.size
            else math.nan, "nodes": int(kept.size), "left_early": int(nodes.size - kept.size)}


def stress_jump_balance(result, width: int = 4) -> dict:
    """Theorem 2.3(1): on each interval of the band (`width` cells about a front) the momentum equation gives
    impulse = stress-jump impulse + inertia exactly, and (2.10) says the inertia vanishes in the limit: the totals,
    the mismatch |impulse − stress jump| / impulse, the closure, the bands' share and Figure 1's per-row series."""
    dt = result.scene.dt
    m = nodal_weights(result)
    terms, h = momentum_terms(result), np.diff(result.x)[None, :]
    S = np.diff(terms.eta_s, axis=1) / h + result.scene.alpha * np.diff(terms.q_s, axis=1) / h  # η_x + α η_tx, cells
    front = free_boundary(result.contact, np.ones((1, 3), dtype=bool))  # the fronts in space at each row
    front[:, [0, -1]] = False
    band = ndimage.binary_dilation(front, structure=np.ones((1, 2 * width + 1), dtype=bool))
    N, rows, F, v = result.x.size, result.t.size, terms.force, terms.q
    I_row, J_row, K_row = np.zeros((3, rows))
    for n in range(1, rows):
        for a, b in _runs(band[n]):
            if a < 1 or b > N - 2:
                continue  # the band reaches a fixed end: no stress face outside it
            I_row[n] += dt * np.dot(m[a:b + 1], F[n, a:b + 1])
            J_row[n] += -dt * (S[n, b] - S[n, a - 1])
            K_row[n] += np.dot(m[a:b + 1], v[n, a:b + 1] - v[n - 1, a:b + 1])
    I_tot, J_tot, K_tot = I_row.sum(), J_row.sum(), K_row.sum()
    total = impulse(result).sum()
    return {"band_impulse": float(I_tot), "stress_jump_impulse": float(J_tot), "inertia": float(K_tot),
            "mismatch": float(abs(I_tot - J_tot) / I_tot) if I_tot > 0 else math.nan,
            "identity_closure": float(abs(I_tot - J_tot - K_tot) / max(I_tot, 1e-300)),
            "band_share": float(I_tot / total) if total > 0 else math.nan,
            "impulse_rate": I_row / dt, "stress_jump_rate": J_row / dt}


def landing_segments(result, min_nodes: int = 10) -> list[tuple[int, int, int]]:
    """(row, first node, last node) of the maximal runs of ≥ `min_nodes` interior nodes landing within one step."""
    first = first_contact_rows(result)
    ok = interior(result) & (first >= 1)
    found = sorted(((int(n), a, b) for n in np.unique(first[ok])
                    for a, b in _runs(ok & ((first == n) | (first == n + 1)), min_nodes)), key=lambda s: s[1] - s[2])
    kept = []
    for n, a, b in found:  # drop runs inside an already kept one
        if not any(a >= a2 and b <= b2 for _, a2, b2 in kept):
            kept.append((n, a, b))
    return sorted(kept, key=lambda s: (s[0], s[1]))


def landing_impulse(result, margin: int = 4, decay_eps: float = 12.0) -> dict:
    """Theorem 2.3(2): on a segment landing at once (less `margin` nodes a side) the impulse density over the window
    [n₀, n₀ + q] (q ≈ `decay_eps`·ε/Δt) against the jump of v (2.12), and the window's share of the impulse."""
    dt = result.scene.dt
    q = max(2, int(math.ceil(decay_eps * result.scene.eps / dt))) if penalised(result) else 2
    terms, rows = momentum_terms(result), result.t.size
    F, v = terms.force, terms.q
    density, jump, share, times = [], [], [], []
    for n0, a, b in landing_segments(result):
        a, b = a + margin, b - margin
        if b < a or n0 + q + 1 >= rows:
            continue
        f, total = dt * F[n0:n0 + q + 1, a:b + 1].sum(axis=0), dt * F[:, a:b + 1].sum(axis=0)
        density.append(f)
        jump.append(v[n0 + q + 1, a:b + 1] - v[n0 - 1, a:b + 1])
        share.append(f.sum() / total.sum() if total.sum() > 0 else math.nan)
        times.append(result.t[n0])
    if not density:
        return {"segments": 0}
    f, jmp = np.concatenate(density), np.concatenate(jump)
    return {"segments": len(density), "times": times, "mean_density": float(f.mean()), "mean_jump": float(jmp.mean()),
            "window_share": float(np.nanmin(share)), "window_steps": q + 1}


def penalised(result) -> bool:
    """Whether the result's scheme brakes with a penalty (ε), or stops a node within a step (no ε)."""
    return result.penalty not in (None, "none")
