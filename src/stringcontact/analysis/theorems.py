r"""The paper's structural results, measured on computed solutions.

The paper proves statements about the *limit* ε, h, Δt → 0. A computed solution is a penalised, discrete
one, so every check below measures a number, states what the theorem predicts for it (usually: a limit
under refinement) and gives a verdict. Where the discrete scheme cannot satisfy a statement the verdict
says so, with the number.

All checks are plain functions of a :class:`~stringcontact.io.result.Result` that stores **every** time step
(``simulate(scene, max_rows=scene.nt)``), in the scheme's own discrete terms (lumped P1 = the paper's
finite differences). With row ``n`` of the result:

* ``F^n`` is the force density applied in the step t_{n−1} → t_n, so the nodal impulse of that step is
  ``I^n_j = Δt m_j F^n_j`` (``m_j = Δx`` inside). It is ``contact_force[n]``, except for the explicit
  penalty, whose stored row n is the paper's F(η^n, v^n), applied in the *next* step (`momentum_terms`);
* every scheme's step reads as a discrete momentum equation of node j, with the stress ``S = η_x + α q_x``
  on the cells (`momentum_terms`: which velocity q changes and at which time levels S is taken),

  .. math:: m_j F^n_j = m_j (q^n_j − q^{n−1}_j)/Δt − (S^n_{j+1/2} − S^n_{j−1/2}),

  ``paper``: q = v^n = (η^n − η^{n−1})/Δt (its stored velocity) and S at t_n; ``projection``: q the same
  backward quotient (its stored velocity is the centred one), S with η at t_{n−1} (explicit elastic term);
  ``newmark``: q its nodal velocity and S the mean of t_{n−1} and t_n,

  which is the discrete form of Theorem 2.3(1): summed over a band around a free boundary, the impulse
  equals minus the stress jump across the band plus the inertia inside it, and the theorem says the
  inertia vanishes in the limit.

The checks:

=====================  ==================================================================================
``a1_sign``            (A1) F ≥ 0 and D ≥ 0 (D both as the paper's F·(η_t)⁻ and as the energy actually
                       removed per step, −F^n v^n, which the explicit penalty can make negative)
``a2_support``         (A2) fraction of the impulse within k = 1, 2, 4 cells or steps of the discrete free
                       boundary ∂{η ≤ 0}, and the space-time measure of supp F
``a3_upward``          (A3) impulse applied where the string moves up (pointwise, and on a neighbourhood)
``a4_velocity``        (A4)/Theorem 2.2: |v| a fixed delay after each node's first contact / impact speed
``stress_jump``        Theorem 2.3(1): impulse in a band around the moving fronts vs −[S] across the band
``flat_landing``       Theorem 2.3(2): impulse per unit length of a segment landing at once vs the
                       velocity jump (= V for the exact α = 0 case)
``energy_balance``     (1.4): E(0) = E(t) + D_visc + D_con (+ the scheme's D_num), as a time series
=====================  ==================================================================================

Trends come from :func:`refine`, which reruns a scene at coarser resolutions with the same ratios
Δt/Δx and r = Δt/ε, so ε, h and Δt all fall together.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..run.checks import energy_balance

FLAT_LANDING = "flat-landing"
STRESS_JUMP = "Thm 2.3(1) F = -[eta_x + a eta_tx]"
HOLDS, FAILS, BY_CONSTRUCTION, NOT_APPLICABLE = "holds", "fails", "holds by construction", "n/a"


@dataclass(frozen=True)
class Check:
    """One measured statement: the number, what the theory expects of it, and the verdict."""

    name: str
    measured: float
    expectation: str
    verdict: str
    detail: str = ""
    trend: tuple = ()  # ((label, value), ...) over refinement levels, coarse to fine
    extra: dict = field(default_factory=dict)
    data: dict = field(default_factory=dict, repr=False, compare=False)  # finest level's full measurement, not saved

    def as_dict(self) -> dict:
        return {
            "name": self.name,
            "measured": self.measured,
            "expectation": self.expectation,
            "verdict": self.verdict,
            "detail": self.detail,
            "trend": [list(p) for p in self.trend],
            "extra": self.extra,
        }


# --- the discrete fields --------------------------------------------------------------------------------


def _require_every_step(result) -> None:
    steps = np.asarray(result.steps)
    if steps.size < 2 or np.any(np.diff(steps) != 1) or steps[0] != 0:
        raise ValueError(
            "the theorem checks need every time step stored: run simulate(scene, max_rows=scene.nt)"
        )


def nodal_weights(result) -> np.ndarray:
    """Lumped P1 mass m_j of the nodes (Δx/2 at the ends) on the result's grid."""
    dx = np.diff(result.x)
    m = np.zeros_like(result.x)
    m[:-1] += 0.5 * dx
    m[1:] += 0.5 * dx
    return m


def impulse(result) -> np.ndarray:
    """Nodal contact impulse Δt m_j F^n_j of every step, shape (rows, nodes); row 0 is zero."""
    return result.scene.dt * momentum_terms(result).force * nodal_weights(result)[None, :]


def interior(result) -> np.ndarray:
    mask = np.ones(result.x.size, dtype=bool)
    mask[[0, -1]] = False
    return mask


def free_boundary(contact: np.ndarray) -> np.ndarray:
    """The discrete free boundary ∂{η ≤ 0} on the (step, node) grid.

    A grid point belongs to it when its contact flag differs from one of its four neighbours (both
    sides of the interface are marked, so the boundary is two points thick and symmetric).
    """
    c = np.asarray(contact, dtype=bool)
    b = np.zeros_like(c)
    for axis in (0, 1):
        diff = np.diff(c, axis=axis)
        lo = [slice(None)] * 2
        hi = [slice(None)] * 2
        lo[axis] = slice(None, -1)
        hi[axis] = slice(1, None)
        b[tuple(lo)] |= diff
        b[tuple(hi)] |= diff
    return b


def distance_to_free_boundary(contact: np.ndarray) -> np.ndarray:
    """Chessboard distance (in cells or steps, whichever is larger) of each grid point to ∂{η ≤ 0}.

    Points with no free boundary at all get a large distance.
    """
    from scipy import ndimage

    b = free_boundary(contact)
    if not b.any():
        return np.full(b.shape, np.iinfo(np.int32).max, dtype=np.int64)
    return ndimage.distance_transform_cdt(~b, metric="chessboard").astype(np.int64)


def _previous(rows: np.ndarray) -> np.ndarray:
    """Row n holds row n − 1 (row 0 itself)."""
    return np.concatenate([rows[:1], rows[:-1]])


@dataclass(frozen=True)
class Momentum:
    """A scheme's discrete momentum equation at each row n (see the module docstring), arrays over (rows,
    nodes): q, the velocity whose change is the inertia; S = (η_S)_x + α (q_S)_x, the stress; w, the velocity
    the scheme's ledger books the contact work with (−Δt F·w per step); F, the force density applied in the
    step t_{n−1} → t_n (row 0: none)."""

    q: np.ndarray
    eta_s: np.ndarray
    q_s: np.ndarray
    w: np.ndarray
    force: np.ndarray


def momentum_terms(result) -> Momentum:
    """The terms of `result.scheme`'s discrete momentum equation (`Momentum`)."""
    _require_every_step(result)
    eta, v, F, scheme = result.eta, result.velocity, result.contact_force, result.scheme
    if scheme == "projection":
        q = np.concatenate([v[:1], np.diff(eta, axis=0) / result.scene.dt])  # the half-step velocities
        return Momentum(q, _previous(eta), q, 0.5 * (q + _previous(q)), F)
    if scheme == "newmark":
        mean = 0.5 * (v + _previous(v))
        return Momentum(v, 0.5 * (eta + _previous(eta)), mean, mean, F)
    if result.penalty == "explicit":  # row n holds F(η^n, v^n), which the step t_n → t_{n+1} applies
        F = np.concatenate([np.zeros_like(F[:1]), F[:-1]])
    return Momentum(v, eta, v, v, F)


def cell_stress(result) -> np.ndarray:
    """S = η_x + α η_tx on the cells at every row (one-sided difference quotients, at the scheme's time
    levels: `momentum_terms`), shape (rows, cells)."""
    dx = np.diff(result.x)[None, :]
    terms = momentum_terms(result)
    return np.diff(terms.eta_s, axis=1) / dx + result.scene.alpha * np.diff(terms.q_s, axis=1) / dx


def first_contact_rows(result) -> np.ndarray:
    """Row of each node's first contact (η ≤ 0); −1 if never, 0 if in contact from the start."""
    c = np.asarray(result.contact, dtype=bool)
    first = np.argmax(c, axis=0)
    return np.where(c.any(axis=0), first, -1)


def _runs(mask: np.ndarray, min_nodes: int = 1) -> list[tuple[int, int]]:
    """Maximal runs [a, b] (inclusive node indices) of at least `min_nodes` True in a 1-D mask."""
    from ..plot.charts import contact_components

    return [(int(a), int(b)) for a, b in contact_components(np.arange(np.size(mask)), mask, min_nodes)]


def _band_width(result, delta: float) -> int:
    """Half-width in cells (at least 1) of the band of physical half-width `delta` around the fronts."""
    return max(1, int(round(delta / float(np.diff(result.x).mean()))))


def _dilate_1d(mask: np.ndarray, w: int) -> np.ndarray:
    """Nodes within w of a True node (along the last axis)."""
    if w <= 0:
        return mask.copy()
    from scipy import ndimage

    structure = np.zeros((1, 2 * w + 1) if mask.ndim == 2 else (2 * w + 1,), dtype=bool)
    structure[..., :] = True
    return ndimage.binary_dilation(mask, structure=structure)


# --- measurements: plain numbers from one result ------------------------------------------------------


def force_sign(result) -> dict:
    """min F / max F, and the share of the energy-carrying contact dissipation −F^n w^n that is negative (w the
    velocity the scheme books the contact work with: `momentum_terms`)."""
    terms = momentum_terms(result)
    F = result.contact_force
    D = -terms.force[1:] * terms.w[1:]
    positive = D[D > 0].sum()
    return {
        "min_force": float(F.min()),
        "max_force": float(F.max()),
        "paper_dissipation_min": float((F * np.maximum(-result.velocity, 0.0)).min()),
        "negative_dissipation_share": float(-D[D < 0].sum() / positive) if positive > 0 else 0.0,
    }


def support_concentration(result, ks=(1, 2, 4), lengths=()) -> dict:
    """Share of the total impulse within k cells/steps of ∂{η ≤ 0}, for each k and each physical length.

    `lengths` are distances in the units of x and t (converted to whole cells/steps on this grid): the
    share within a *fixed physical* distance must tend to 1 if F concentrates on a null set.
    """
    I = impulse(result)
    total = I.sum()
    d = distance_to_free_boundary(result.contact)
    step = max(float(np.diff(result.x).max()), result.scene.dt)
    out = {"support_measure": float((I > 0).sum() * result.scene.dt * float(np.diff(result.x).mean()))}
    for k in ks:
        out[f"within_{k}"] = float(I[d <= k].sum() / total) if total > 0 else math.nan
    for L in lengths:
        k = max(0, int(math.floor(L / step + 1e-9)))
        out[f"within_length_{L:g}"] = float(I[d <= k].sum() / total) if total > 0 else math.nan
    return out


def upward_impulse(result) -> dict:
    """Share of the impulse applied where the string moves up.

    pointwise: in the same step, v^n_j ≥ 0. neighbourhood: v ≥ 0 on all of rows n−1..n+1, nodes j−1..j+1
    (a discrete int{η_t ≥ 0}, the set of (A3)).
    """
    from scipy import ndimage

    I = impulse(result)
    total = I.sum()
    up = result.velocity >= 0  # row 0 is v0, which sets the force of the first step
    nbhd = ndimage.binary_erosion(up, structure=np.ones((3, 3), dtype=bool), border_value=1)
    share = (lambda mask: float(I[mask].sum() / total)) if total > 0 else (lambda mask: math.nan)
    return {"pointwise": share(up), "neighbourhood": share(nbhd)}


def velocity_after_contact(result, delay: float) -> dict:
    """|v| a time `delay` after each node's first contact, against its impact speed |v| at contact.

    Only nodes that touch down after t = 0, stay in contact until t_0 + delay and have the delay inside
    the run count. Gives the aggregate ratio Σ|v(t_0+delay)| / Σ|v(t_0)| and the 95th percentile of the
    node ratios (nodes with at least 1% of the largest impact speed).
    """
    _require_every_step(result)
    first = first_contact_rows(result)
    lag = max(1, int(round(delay / result.scene.dt)))
    nodes = np.flatnonzero(interior(result) & (first >= 1) & (first + lag < result.t.size))
    c = np.asarray(result.contact, dtype=bool)
    stays = np.array([c[first[j]:first[j] + lag + 1, j].all() for j in nodes], dtype=bool)
    kept = nodes[stays] if nodes.size else nodes
    if kept.size == 0:
        return {"ratio": math.nan, "p95": math.nan, "nodes": 0, "left_early": int(nodes.size)}
    impact = np.abs(result.velocity[first[kept], kept])
    after = np.abs(result.velocity[first[kept] + lag, kept])
    big = impact >= 0.01 * impact.max()
    ratios = after[big] / impact[big]
    return {
        "ratio": float(after.sum() / impact.sum()),
        "p95": float(np.percentile(ratios, 95)) if ratios.size else math.nan,
        "nodes": int(kept.size),
        "left_early": int(nodes.size - kept.size),
    }


def stress_jump_balance(result, width: int = 4) -> dict:
    """Theorem 2.3(1) in the scheme's terms: impulse in a band around the fronts vs −[S] across it.

    At each row the band is every node within `width` cells of a spatial front of {η ≤ 0}. On each band
    interval [a, b] (away from the ends) the discrete momentum equation gives exactly

        Σ_j m_j F^n_j Δt = −(S_{b+½} − S_{a−½}) Δt + Σ_j m_j (v^n_j − v^{n−1}_j),

    impulse = stress-jump impulse + inertia; (2.10) says the inertia vanishes in the limit. Returns the
    three totals, the relative mismatch |impulse − stress jump| / impulse, the closure of the identity, the
    share of all impulse that lies in the bands, and per-row series (for the figure).
    """
    _require_every_step(result)
    dt = result.scene.dt
    m = nodal_weights(result)
    c = np.asarray(result.contact, dtype=bool)
    S = cell_stress(result)
    front = np.zeros_like(c)
    d = np.diff(c, axis=1)
    front[:, :-1] |= d
    front[:, 1:] |= d
    front[:, [0, -1]] = False
    band = _dilate_1d(front, width)
    N = result.x.size
    rows = result.t.size
    I_row, J_row, K_row = np.zeros(rows), np.zeros(rows), np.zeros(rows)
    terms = momentum_terms(result)
    F, v = terms.force, terms.q
    for n in range(1, rows):
        for a, b in _runs(band[n]):
            if a < 1 or b > N - 2:
                continue  # the band reaches a fixed end: no stress face outside it
            I_row[n] += dt * np.dot(m[a:b + 1], F[n, a:b + 1])
            J_row[n] += -dt * (S[n, b] - S[n, a - 1])
            K_row[n] += np.dot(m[a:b + 1], v[n, a:b + 1] - v[n - 1, a:b + 1])
    I_tot, J_tot, K_tot = I_row.sum(), J_row.sum(), K_row.sum()
    total = impulse(result).sum()
    return {
        "band_impulse": float(I_tot),
        "stress_jump_impulse": float(J_tot),
        "inertia": float(K_tot),
        "mismatch": float(abs(I_tot - J_tot) / I_tot) if I_tot > 0 else math.nan,
        "identity_closure": float(abs(I_tot - J_tot - K_tot) / max(I_tot, 1e-300)),
        "band_share": float(I_tot / total) if total > 0 else math.nan,
        "impulse_rate": I_row / dt,
        "stress_jump_rate": J_row / dt,
    }


def landing_segments(result, min_nodes: int = 10) -> list[tuple[int, int, int]]:
    """Segments that land at once: maximal runs of ≥ `min_nodes` interior nodes whose first contact
    (after t = 0) falls within one step, as (row, first node, last node)."""
    first = first_contact_rows(result)
    ok = interior(result) & (first >= 1)
    found = []
    for n in np.unique(first[ok]):
        mask = ok & ((first == n) | (first == n + 1))
        found += [(int(n), a, b) for a, b in _runs(mask, min_nodes)]
    found.sort(key=lambda s: s[2] - s[1], reverse=True)
    kept = []
    for n, a, b in found:  # drop runs inside an already kept one
        if not any(a >= a2 and b <= b2 for _, a2, b2 in kept):
            kept.append((n, a, b))
    return sorted(kept, key=lambda s: (s[0], s[1]))


def landing_impulse(result, margin: int = 4, decay_eps: float = 12.0) -> dict:
    """Theorem 2.3(2): impulse per unit length of each segment landing at once vs its velocity jump.

    For each node of a segment (less `margin` nodes at each side) the impulse density Σ Δt F^n over the
    landing window [n₀, n₀ + q] (q steps ≈ `decay_eps`·ε, over which the penalty stops the node) is compared
    with the jump v(after) − v(before) of (2.12), and with the share of the node's whole impulse that falls
    in the window. For the exact α = 0 case the jump is V.
    """
    _require_every_step(result)
    dt = result.scene.dt
    q = max(2, int(math.ceil(decay_eps * result.scene.eps / dt))) if _penalised(result) else 2
    terms = momentum_terms(result)
    F, v = terms.force, terms.q
    rows = result.t.size
    density, jump, share, times = [], [], [], []
    for n0, a, b in landing_segments(result):
        a, b = a + margin, b - margin
        if b < a or n0 + q + 1 >= rows:
            continue
        nodes = np.arange(a, b + 1)
        f = dt * F[n0:n0 + q + 1, nodes].sum(axis=0)
        total = dt * F[:, nodes].sum(axis=0)
        density.append(f)
        jump.append(v[n0 + q + 1, nodes] - v[n0 - 1, nodes])
        share.append(f.sum() / total.sum() if total.sum() > 0 else math.nan)
        times.append(result.t[n0])
    if not density:
        return {"segments": 0}
    f, jmp = np.concatenate(density), np.concatenate(jump)
    return {
        "segments": len(density),
        "times": times,
        "mean_density": float(f.mean()),
        "mean_jump": float(jmp.mean()),
        "window_share": float(np.nanmin(share)),
        "window_steps": q + 1,
    }


# --- scenes and refinement ----------------------------------------------------------------------------


def flat_landing_scene(nx: int = 1000, nt: int = 1200, r: float = 0.4):
    """:func:`stringcontact.analysis.study.flat_landing_scene` (the exact α = 0 case, `exact.flat_landing`: η0 = h,
    v0 = −V, ends at h, T = 0.6) with ε = Δt/r."""
    from .study import flat_landing_scene as flat

    return flat(nx, nt=nt, eps=0.6 / nt / r)


def coarsened(scene, factor: int):
    """The scene with nx, nt divided by `factor` and ε scaled so that r = Δt/ε stays the same."""
    nx, nt = max(2, round(scene.nx / factor)), max(1, round(scene.nt / factor))
    return scene.replace(nx=nx, nt=nt, eps=scene.eps * scene.nt / nt)


def refine(scene, levels: int = 3, penalty: str | None = "explicit", model=None, scheme: str | None = None):
    """Results at resolutions scene/2^(levels−1), ..., scene/2, scene (coarse to fine), every step stored,
    with `scheme` (default: the scene's, else "paper") and its `penalty` (None: the scheme's own).

    Δx, Δt and ε fall together (fixed Δt/Δx and r = Δt/ε), the limit the paper's theorems describe; an
    ε-free scheme (projection) refines Δx and Δt only.
    """
    from ..run.driver import simulate

    if levels < 1:
        raise ValueError(f"levels must be >= 1, got {levels}")
    out = []
    for k in reversed(range(levels)):
        s = coarsened(scene, 2**k)
        out.append(simulate(s, scheme=scheme, penalty=penalty, max_rows=s.nt, model=model,
                            gather="all"))  # every rank checks the same rows
    return out


def refine_time(scene, levels: int = 3, penalty: str | None = "explicit", model=None, scheme: str | None = None):
    """Results with Δt, Δt/2, Δt/4, ... at fixed Δx and ε (only the energies are used: rows thinned)."""
    from ..run.driver import simulate

    return [simulate(scene.replace(nt=scene.nt * 2**k), scheme=scheme, penalty=penalty, model=model, gather="all")
            for k in range(levels)]


# --- checks: a number, an expectation and a verdict ----------------------------------------------------

HOLDS_IN_LIMIT, INCONCLUSIVE = "holds in the limit", "inconclusive"


def _penalised(result) -> bool:
    """Whether the result's scheme brakes with a penalty (ε), or stops a node within a step (no ε)."""
    return result.penalty not in (None, "none")


def _falls(values) -> bool:
    v = [x for x in values if not math.isnan(x)]
    return len(v) >= 2 and all(b < a for a, b in zip(v, v[1:]))


def _label(result) -> str:
    s = result.scene
    return f"nx={s.nx}"


def _trend(results, values) -> tuple:
    return tuple((_label(r), float(v)) for r, v in zip(results, values))


def _as_list(results):
    return list(results) if isinstance(results, (list, tuple)) else [results]


def check_force_sign(results) -> Check:
    """(A1) F ≥ 0 (and the paper's D = F (η_t)⁻ ≥ 0, which follows from it)."""
    results = _as_list(results)
    m = [force_sign(r) for r in results]
    worst = min(x["min_force"] for x in m)
    scale = max(max(x["max_force"] for x in m), 1e-300)
    return Check(
        "(A1) F >= 0, D = F(eta_t)^- >= 0", worst / scale, "min F / max F >= 0",
        HOLDS if worst >= 0 and min(x["paper_dissipation_min"] for x in m) >= 0 else FAILS,
        detail=f"max F = {scale:.4g}", trend=_trend(results, [x["min_force"] / scale for x in m]),
    )


def check_dissipation_sign(results) -> Check:
    """(A1) for the energy the scheme actually removes, −F^n v^n: its negative share must vanish."""
    results = _as_list(results)
    vals = [force_sign(r)["negative_dissipation_share"] for r in results]
    last = vals[-1]
    verdict = HOLDS if last == 0 else (HOLDS_IN_LIMIT if _falls(vals) else (FAILS if len(vals) > 1 else INCONCLUSIVE))
    return Check(
        "(A1) removed energy -F^n v^n >= 0", last, "negative share 0, or -> 0 under refinement", verdict,
        detail="negative where the node moves up in the step after the force was set (explicit penalty)",
        trend=_trend(results, vals),
    )


def check_support(results, ks=(1, 2, 4)) -> Check:
    """(A2) the impulse concentrates at ∂{η = 0}: the share outside a fixed physical distance → 0."""
    results = _as_list(results)
    coarse = results[0]
    L = 4 * max(float(np.diff(coarse.x).max()), coarse.scene.dt)
    m = [support_concentration(r, ks=ks, lengths=(L,)) for r in results]
    outside = [1 - x[f"within_length_{L:g}"] for x in m]
    fine = m[-1]
    within = ", ".join(f"k={k}: {fine[f'within_{k}']:.3f}" for k in ks)
    if abs(outside[-1]) <= 1e-12:  # 1 minus a share that is 1 up to the round-off of its sum
        verdict = HOLDS
    elif len(results) < 2:
        verdict = INCONCLUSIVE
    else:
        verdict = HOLDS_IN_LIMIT if _falls(outside) and outside[-1] < 0.75 * outside[-2] else FAILS
    return Check(
        "(A2) supp F near the free boundary", outside[-1],
        f"impulse share farther than {L:.3g} from the free boundary -> 0", verdict,
        detail=f"share within k cells/steps: {within}; |supp F| = {fine['support_measure']:.3g}",
        trend=_trend(results, outside),
        extra={"within_k": {k: fine[f"within_{k}"] for k in ks}, "length": L,
               "support_measure": [x["support_measure"] for x in m]},
    )


def check_upward(results) -> list[Check]:
    """(A3): no impulse where the string moves up, on a neighbourhood (the theorem's set) and pointwise."""
    results = _as_list(results)
    m = [upward_impulse(r) for r in results]
    nb = [x["neighbourhood"] for x in m]
    pw = [x["pointwise"] for x in m]
    explicit = results[-1].penalty == "explicit"
    nb_verdict = (BY_CONSTRUCTION if explicit else HOLDS) if nb[-1] == 0 else FAILS
    pw_verdict = HOLDS if pw[-1] == 0 else (HOLDS_IN_LIMIT if _falls(pw) else (FAILS if len(pw) > 1 else INCONCLUSIVE))
    return [
        Check("(A3) impulse where v >= 0 on a 3x3 nbhd", nb[-1], "0", nb_verdict,
              detail="explicit: F^n is set by v^{n-1} < 0, which lies in every neighbourhood"
              if nb_verdict == BY_CONSTRUCTION else "",
              trend=_trend(results, nb)),
        Check("(A3) impulse where v^n >= 0 (same step)", pw[-1], "-> 0 under refinement", pw_verdict,
              trend=_trend(results, pw)),
    ]


def check_velocity_after_contact(results, delay: float | None = None) -> Check:
    """(A4)/Theorem 2.2: |v| a fixed delay after first contact, relative to the impact speed, → 0."""
    results = _as_list(results)
    if delay is None:  # the penalty needs a few ε to stop a node; an ε-free scheme stops it within a step
        finest = results[-1]
        delay = 8 * finest.scene.eps if _penalised(finest) else 2 * finest.scene.dt
    m = [velocity_after_contact(r, delay) for r in results]
    vals = [x["ratio"] for x in m]
    if math.isnan(vals[-1]):
        verdict = NOT_APPLICABLE
    elif vals[-1] == 0:
        verdict = HOLDS
    elif len(vals) < 2:
        verdict = INCONCLUSIVE
    else:
        verdict = HOLDS_IN_LIMIT if _falls(vals) else FAILS
    fine = m[-1]
    return Check(
        "(A4) |v| after contact / impact speed", vals[-1], f"-> 0 under refinement (delay {delay:.3g})", verdict,
        detail=f"{fine['nodes']} nodes, 95th percentile {fine['p95']:.3g}, {fine['left_early']} left contact earlier",
        trend=_trend(results, vals), extra={"delay": delay},
    )


def check_stress_jump(results, delta: float = 0.02) -> Check:
    """Theorem 2.3(1), formula (2.10): impulse near a moving front = −[η_x + α η_tx] across it."""
    results = _as_list(results)
    m = [stress_jump_balance(r, _band_width(r, delta)) for r in results]
    vals = [x["mismatch"] for x in m]
    fine = m[-1]
    if math.isnan(vals[-1]) or results[-1].scene.alpha == 0:
        verdict = NOT_APPLICABLE  # (2.10) needs eta in H^1(H^1), i.e. alpha > 0; at alpha = 0 fronts carry [eta_t]
    elif vals[-1] <= 0.25 and (len(vals) < 2 or _falls(vals)):
        verdict = HOLDS_IN_LIMIT
    elif vals[-1] >= 0.5:
        verdict = FAILS
    else:
        verdict = INCONCLUSIVE
    return Check(
        STRESS_JUMP, vals[-1], f"|impulse - stress jump|/impulse -> 0 (band +-{delta:g})",
        verdict,
        detail=(f"band impulse {fine['band_impulse']:.4g} ({100 * fine['band_share']:.0f}% of all), stress jump "
                f"{fine['stress_jump_impulse']:.4g}, inertia {fine['inertia']:.4g}; identity closes to "
                f"{fine['identity_closure']:.1e}"),
        trend=_trend(results, vals),
        extra={k: fine[k] for k in ("band_impulse", "stress_jump_impulse", "inertia", "band_share")},
        data=fine,
    )


def check_landing(results, V: float | None = None) -> Check:
    """Theorem 2.3(2): a segment landing at once gets the impulse per unit length = its velocity jump (V)."""
    results = _as_list(results)
    m = [landing_impulse(r) for r in results]
    if m[-1]["segments"] == 0:
        return Check("Thm 2.3(2) landing impulse = [v]", math.nan, "needs a segment landing at once", NOT_APPLICABLE,
                     detail="no segment of >= 10 nodes touches down within one step")
    target = [V if V is not None else x.get("mean_jump", math.nan) for x in m]
    vals = [abs(x["mean_density"] - t) / abs(t) if x["segments"] else math.nan for x, t in zip(m, target)]
    fine = m[-1]
    if vals[-1] <= 0.01:
        verdict = HOLDS
    elif len(vals) > 1 and _falls(vals):
        verdict = HOLDS_IN_LIMIT
    else:  # a few per cent with no trend is no evidence either way
        verdict = INCONCLUSIVE if vals[-1] < 0.05 else FAILS
    what = f"V = {V:g}" if V is not None else "the velocity jump"
    return Check(
        "Thm 2.3(2) landing impulse = [v]", vals[-1], f"|impulse per length - {what}| / {what} -> 0", verdict,
        detail=(f"{fine['segments']} segment(s), first at t = {fine['times'][0]:.4g}; mean impulse/length "
                f"{fine['mean_density']:.4g}, mean jump {fine['mean_jump']:.4g}; {100 * fine['window_share']:.2f}% "
                f"of it within {fine['window_steps']} steps"),
        trend=_trend(results, vals),
    )


def check_energy(result, time_refined=()) -> list[Check]:
    """(1.4): the discrete identity closes to round-off; the continuous one up to D_num, which → 0 with Δt."""
    m = energy_balance(result)  # the run's one energy balance (run.checks), relative to its largest term
    runs = [result, *time_refined]
    cont = [energy_balance(r)["continuous_residual"] for r in runs]
    trend = tuple((f"dt={r.scene.dt:.3g}", v) for r, v in zip(runs, cont))
    if all(v < 1e-9 for v in cont):  # no numerical dissipation (projection, newmark): holds at every Δt
        cont_verdict = HOLDS
    else:
        cont_verdict = INCONCLUSIVE if len(runs) < 2 else (HOLDS_IN_LIMIT if _falls(cont) else FAILS)
    return [
        Check("(1.4) discrete energy identity", m["relative_residual"], "round-off (< 1e-9 E0)",
              HOLDS if m["relative_residual"] < 1e-9 else FAILS, detail=f"E0 = {m['initial']:.6g}"),
        Check("(1.4) without D_num: D_num / E0", m["continuous_residual"], "-> 0 as dt -> 0 (eps, h fixed)",
              cont_verdict, detail=f"D_num / D_con = {m['numerical_over_contact']:.3g}", trend=trend),
    ]


def run_checks(scene, levels: int = 3, penalty: str | None = "explicit", delay: float | None = None,
               delta: float = 0.02, V: float | None = None, time_levels: int = 3, model=None,
               scheme: str | None = None):
    """Every check on `scene` with `levels` fixed-r refinements (the finest is `scene` itself), run with
    `model` (default: the scene's registered model, else the paper's) and `scheme` (default: the scene's,
    else the paper's) with its `penalty` (None: the scheme's own).

    Returns (checks, finest result, all fixed-r results).
    """
    if model is None and scene.model:
        from ..model.registry import load_model

        model = load_model(scene.model)  # a registered name: the scene was checked when it was loaded
    results = refine(scene, levels, penalty, model, scheme)
    timed = refine_time(scene, time_levels, penalty, model, scheme)[1:] if time_levels > 1 else []
    checks = [
        check_force_sign(results),
        check_dissipation_sign(results),
        check_support(results),
        *check_upward(results),
        check_velocity_after_contact(results, delay),
        check_stress_jump(results, delta),
        check_landing(results, V),
        *check_energy(results[-1], timed),
    ]
    return checks, results[-1], results


def format_table(checks) -> str:
    """The checks as a plain-text table: check, measured value, expectation, verdict."""
    head = ("check", "measured", "expectation", "verdict")
    rows = [(c.name, f"{c.measured:.3g}", c.expectation, c.verdict) for c in checks]
    widths = [max(len(r[i]) for r in [head, *rows]) for i in range(4)]
    line = "  ".join("{:%d}" % w for w in widths)
    out = [line.format(*head), line.format(*("-" * w for w in widths))]
    out += [line.format(*r) for r in rows]
    return "\n".join(out)


def format_trends(checks) -> str:
    lines = []
    for c in checks:
        if c.trend:
            lines.append(f"{c.name}: " + ", ".join(f"{lab} {v:.3g}" for lab, v in c.trend))
        if c.detail:
            lines.append(f"    {c.detail}")
    return "\n".join(lines)


# --- the paper's Figure 1 -----------------------------------------------------------------------------


def draw_figure1(result, path, delta: float = 0.02, title: str | None = None, balance: dict | None = None):
    """The paper's Figure 1 on a computed solution: the contact set {η ≤ 0} in the (x, t) plane with its
    free boundary, the contact force density F on it (log colour), and, on the right, the force on the
    fronts per unit time against the stress jump −[η_x + α η_tx] across them (Theorem 2.3(1)).

    `balance` is :func:`stress_jump_balance` of `result` at this `delta` if already computed (the ``data``
    of :func:`check_stress_jump`'s check); otherwise it is computed here.
    """
    from matplotlib.colors import ListedColormap, LogNorm

    from ..plot.charts import pyplot, savefig

    plt = pyplot()
    _require_every_step(result)
    x, t = result.x, result.t
    F = np.ma.masked_less_equal(result.contact_force, 0.0)
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(12, 5), gridspec_kw={"width_ratios": [1.2, 1]})
    extent = (x[0], x[-1], t[0], t[-1])
    ax.imshow(result.contact, origin="lower", aspect="auto", extent=extent,
              cmap=ListedColormap(["white", "0.85"]), interpolation="nearest")
    if F.count():
        im = ax.imshow(F, origin="lower", aspect="auto", extent=extent, cmap="inferno_r",
                       norm=LogNorm(vmin=max(F.max() * 1e-4, F.min()), vmax=F.max()), interpolation="nearest")
        fig.colorbar(im, ax=ax, label="contact force density F")
    if result.contact.any() and not result.contact.all():
        ax.contour(x, t, result.contact.astype(float), levels=[0.5], colors="tab:blue", linewidths=0.8)
    ax.plot([], [], color="tab:blue", label=r"free boundary $\partial\{\eta=0\}$")
    ax.fill_between([], [], color="0.85", label=r"contact set $\{\eta\leq 0\}$")
    ax.set_xlabel("x")
    ax.set_ylabel("t")
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title(title or f"{result.scene.name}: contact set and force")

    sj = balance if balance is not None else stress_jump_balance(result, _band_width(result, delta))
    bx.plot(t, sj["impulse_rate"], color="tab:red", lw=1, label=r"force on the fronts $\sum m_jF_j$")
    bx.plot(t, sj["stress_jump_rate"], color="tab:blue", lw=1, label=r"stress jump $-[\eta_x+\alpha\eta_{tx}]$")
    bx.plot(t, np.sum(impulse(result), axis=1) / result.scene.dt, color="0.5", lw=0.8, ls="--",
            label=r"all force $\int F\,dx$")
    bx.set_yscale("symlog", linthresh=1.0)
    bx.set_xlabel("t")
    bx.set_ylabel("force per unit time")
    bx.set_title(f"Theorem 2.3(1): band +-{delta:g} around the fronts")
    bx.legend(fontsize=8)
    fig.tight_layout()
    savefig(fig, Path(path), dpi=110)
    return path


# --- command line -------------------------------------------------------------------------------------


def add_arguments(parser):
    parser.add_argument("scene", help=f"built-in scene, a .toml file, or '{FLAT_LANDING}' (the exact alpha=0 case)")
    parser.add_argument("--nx", type=int, help="cells of the finest level")
    parser.add_argument("--nt", type=int, help="time steps of the finest level")
    parser.add_argument("--eps", type=float, help="penalty parameter of the finest level")
    parser.add_argument("--alpha", type=float, help="viscosity alpha >= 0")
    from ..scene.names import SCHEMES

    parser.add_argument("--scheme", choices=tuple(SCHEMES),
                        help="time scheme (default: the scene's, else paper); projection refines nx and nt only (no eps)")
    parser.add_argument("--penalty", choices=("explicit", "semi-implicit"),
                        help="the penalty of the paper's scheme (default: the scheme's own, explicit for paper)")
    parser.add_argument("--levels", type=int, default=3,
                        help="refinement levels for the trends (nx, nt, 1/eps halved per level; default 3)")
    parser.add_argument("--delay", type=float,
                        help="(A4) delay after first contact (default 8 eps; 2 dt for an eps-free scheme)")
    parser.add_argument("--delta", type=float, default=0.02, help="Thm 2.3(1) band half-width around fronts")
    parser.add_argument("--out", metavar="DIR", help="write checks.json, checks.txt and figure1.png here")
    parser.add_argument("--force", action="store_true", help="replace a non-empty output folder")


def _scene_from_args(args):
    from ..scene.data import load_scene

    if args.scene == FLAT_LANDING:  # keep r = dt/eps = 0.4 when only the grid is changed
        scene = flat_landing_scene(args.nx or 1000, args.nt or 1200)
        changes = {k: getattr(args, k) for k in ("eps", "alpha") if getattr(args, k) is not None}
    else:
        scene = load_scene(args.scene)
        if scene.dim != 1:
            from ..errors import SceneError

            raise SceneError(f"scene {scene.name!r}: domain {scene.domain!r}: `stringcontact check` is 1D-only (the "
                             "paper's theorems are about the string); allowed: a scene with domain 'interval'")
        changes = {k: getattr(args, k) for k in ("nx", "nt", "eps", "alpha") if getattr(args, k) is not None}
    return scene.replace(**changes) if changes else scene


def command(args) -> int:
    import json
    import warnings

    from .study import FLAT_V

    if not 1 <= args.levels <= 6:
        raise ValueError(f"--levels must be between 1 and 6, got {args.levels}")
    if args.delay is not None and not args.delay > 0:
        raise ValueError(f"--delay must be > 0, got {args.delay}")
    if not args.delta > 0:
        raise ValueError(f"--delta must be > 0, got {args.delta}")
    scene = _scene_from_args(args)
    if args.delay is not None and args.delay >= scene.T:
        raise ValueError(f"--delay must be below T = {scene.T:g}, got {args.delay}")
    if args.out is not None:
        from ..io.folder import check_target

        check_target(args.out, args.force)
    V = FLAT_V if scene.name == FLAT_LANDING else None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", category=UserWarning)  # scene warnings were shown by `show`/`run`
        checks, finest, results = run_checks(scene, args.levels, args.penalty, args.delay, args.delta, V,
                                             scheme=args.scheme)
    if _penalised(finest):
        levels = ", ".join(f"nx={r.scene.nx} nt={r.scene.nt} eps={r.scene.eps:.3g}" for r in results)
        levels += f" (r = dt/eps = {scene.r:.3g})"
    else:
        levels = ", ".join(f"nx={r.scene.nx} nt={r.scene.nt}" for r in results) + " (no eps)"
    print(f"scene {scene.name}, scheme {finest.scheme}: levels {levels}")
    print(format_table(checks))
    print()
    print(format_trends(checks))
    if args.out is not None:
        from ..io.folder import staged_folder

        with staged_folder(args.out, args.force) as partial:  # the whole folder or nothing, under the run lock
            (partial / "checks.json").write_text(json.dumps(
                {"scene": scene.name, "levels": [r.scene.as_dict() for r in results],
                 "checks": [c.as_dict() for c in checks]}, indent=1, default=float))
            (partial / "checks.txt").write_text(format_table(checks) + "\n\n" + format_trends(checks) + "\n")
            balance = next(c.data for c in checks if c.name == STRESS_JUMP)  # computed by run_checks
            draw_figure1(finest, partial / "figure1.png", args.delta, balance=balance)
        target = Path(args.out)
        print(f"wrote {target}")
    return 0
