"""Convergence of the nonlinear models against a fine reference, per scheme, with contact and without.

    .venv/bin/python benchmarks/conv_nonlinear.py                          # the table in docs/howto/nonlinear_models.md
    .venv/bin/python benchmarks/conv_nonlinear.py --scheme paper --model large_deflection --scene contact
    .venv/bin/python benchmarks/conv_nonlinear.py --example1 --sizes 100 200 400 800 1600 --reference 6400

Models: the user's route, ``dataclasses.replace(sc.inelastic, momentum_form=..., stored_energy=...)`` adding
k3 η³ w dx (k3 = 10) and its energy ¼ k3 η⁴,
and the shipped `cubic_foundation` and `large_deflection`. Scenes (`string_scene`): Example 1's
string on smooth data, thrown onto the obstacle (contact) or swinging above it (no contact), T = 0.3, ε = 0.01
fixed under refinement, Δt = Δx/2. For each, the runs at Δx = 1/n are compared with the same scheme and model at
n = --reference (`reference_study`): the L∞(0, T; L²) error of η at the coarsest run's
steps, the pairwise observed orders, and the order fitted over the pairs whose reference is at least 8× finer.
--example1 runs Example 1 itself instead (v0 = −50, T = 0.3, ε = 0.005, Δt = Δx/2) and splits the error in time:
the pairwise orders of the error over the landing (t ≤ 0.1) and of the error at T. Writes
benchmarks/out/conv_nonlinear.json.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import platform
import time
import warnings
from pathlib import Path

import numpy as np
import ufl

import stringcontact as sc
from stringcontact.analysis.convergence import (common_rows, errors_against_reference, fitted_order, l2_norm,
                                                observed_orders, to_nodes)
from stringcontact.analysis.problems import METHODS, Method, run_method
from stringcontact.model import nonlinear

K3 = 10.0


def user_form(eta, eta_t, eta_tt, force, w, p):
    """The paper's form plus k3 η³ w dx: the route a user takes."""
    return sc.inelastic.momentum_form(eta, eta_t, eta_tt, force, w, p) + K3 * eta**3 * w * ufl.dx


def user_energy(eta, p):
    """What `user_form` stores: ½η_x² + ¼ k3 η⁴."""
    return 0.5 * ufl.inner(ufl.grad(eta), ufl.grad(eta)) + 0.25 * K3 * eta**4


#: The refinement study's scenes (`string_scene`): T, the penalty's ε (fixed under refinement) and Δt/Δx.
STRING_T, STRING_EPS, STRING_DT_DX = 0.3, 0.01, 0.5


def string_scene(n: int, *, contact: bool, T: float = STRING_T, eps: float = STRING_EPS, dt_dx: float = STRING_DT_DX):
    """Example 1's string at Δx = 1/n, Δt = `dt_dx` Δx: ``contact=True`` thrown down from η0 = ½ + ½ sin(πx) at
    v0 = −8 sin(πx) (lands at t ≈ 0.1), else swinging from rest above the obstacle."""
    data = {"eta0": "0.5 + 0.5*sin(pi*x)", "v0": "-8*sin(pi*x)"} if contact else {"eta0": "1 + 0.5*sin(pi*x)", "v0": "0"}
    return sc.load_scene("example1").replace(
        name="string-contact" if contact else "string-free", notes="", T=T, eps=eps, nx=n,
        nt=max(1, round(T * n / dt_dx)), output_times=[], **data)


#: `reference_study`'s methods: each scheme with the scene's ε, fixed under refinement (the penalised model).
SCHEME_METHODS = {
    "paper": Method("paper", "paper: explicit penalty, lumped, the scene's ε", "explicit", "lumped", "fixed"),
    "projection": METHODS["projection"],
    "newmark": Method("newmark", "newmark: semi-implicit penalty, lumped, the scene's ε", "semi-implicit", "lumped",
                      "fixed", scheme="newmark")}


def reference_study(scene_at, scheme: str, sizes, reference_n: int, *, model=None) -> dict:
    """``err_eta`` of `scheme` on ``scene_at(n)`` per n in `sizes` against ``scene_at(reference_n)``: {"sizes",
    "errors", "orders" (pairwise, in Δx), "reference", "runs"}."""
    method = SCHEME_METHODS[scheme]
    rows = scene_at(min(sizes)).nt
    reference = run_method(scene_at(reference_n), method, rows=rows, model=model)
    runs = [run_method(scene_at(n), method, rows=rows, model=model) for n in sizes]
    errors = [errors_against_reference(run, reference)["err_eta"] if run.status == "complete" else math.nan
              for run in runs]
    orders = observed_orders([1.0 / n for n in sizes], errors)
    return {"sizes": list(sizes), "errors": errors, "orders": [float(p) for p in orders], "reference": reference,
            "runs": runs}


MODELS = {
    "user cubic": dataclasses.replace(sc.inelastic, name="user_cubic", momentum_form=user_form, stored_energy=user_energy),
    "cubic_foundation": nonlinear.cubic_foundation,
    "large_deflection": nonlinear.large_deflection,
}
SCHEMES = ("paper", "projection", "newmark")


def example1_at(n: int):
    return sc.load_scene("example1").replace(T=0.3, eps=0.005, nx=n, nt=round(0.6 * n), output_times=[])


def split_orders(out: dict, landing: float = 0.1) -> tuple[list, list]:
    """Pairwise orders of the L∞(0, landing; L²) error and of the L² error at T."""
    ref, early, final = out["reference"], [], []
    for run in out["runs"]:
        e = l2_norm(run.x, run.eta - to_nodes(ref.x, ref.eta[common_rows(run.t, ref.t)], run.x))
        early.append(float(np.max(e[run.t <= landing + 1e-12])))
        final.append(float(e[-1]))
    h = [1.0 / n for n in out["sizes"]]
    return [float(p) for p in observed_orders(h, early)], [float(p) for p in observed_orders(h, final)]


def one(scheme: str, model: str, scene: str, sizes, reference_n: int, example1: bool) -> dict:
    def scene_at(n):
        return example1_at(n) if example1 else string_scene(n, contact=scene == "contact")

    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = reference_study(scene_at, scheme, sizes, reference_n, model=MODELS[model])
    ref = out["reference"]
    far = [i for i, n in enumerate(sizes) if reference_n >= 8 * n]  # the reference's own error is small beside theirs
    fit = fitted_order([1.0 / sizes[i] for i in far], [out["errors"][i] for i in far]) if len(far) >= 2 else math.nan
    early, final = split_orders(out)
    return {"scheme": scheme, "model": model, "scene": "example1" if example1 else scene, "sizes": list(sizes),
            "reference": reference_n, "errors": out["errors"], "orders": out["orders"], "fitted": fit,
            "orders_landing": early, "orders_at_T": final,
            "min_eta_reference": float(ref.min_eta), "wall_s": time.perf_counter() - t0}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scheme", nargs="+", default=list(SCHEMES), choices=SCHEMES)
    parser.add_argument("--model", nargs="+", default=list(MODELS), choices=list(MODELS))
    parser.add_argument("--scene", nargs="+", default=["contact", "no contact"], choices=["contact", "no contact"])
    parser.add_argument("--sizes", nargs="+", type=int, default=[60, 120, 240, 480])
    parser.add_argument("--reference", type=int, default=3840)
    parser.add_argument("--example1", action="store_true")
    args = parser.parse_args()
    scenes = ["example1"] if args.example1 else args.scene
    sizes = sorted(args.sizes)
    print(f"nx = {', '.join(map(str, sizes))} against nx = {args.reference}; {platform.node()} "
          f"({platform.processor() or platform.machine()})", flush=True)
    split = " | orders, t ≤ 0.1 | orders at T" if args.example1 else ""
    print("| scheme | model | scene | " + " | ".join(f"error, nx = {n}" for n in sizes)
          + f" | pairwise orders | fitted order | min η (reference){split} |", flush=True)
    print("| --- " * (len(sizes) + 6 + 2 * args.example1) + "|", flush=True)
    rows = []
    for scheme in args.scheme:
        for model in args.model:
            for scene in scenes:
                r = one(scheme, model, scene, sizes, args.reference, args.example1)
                rows.append(r)
                print(f"| {scheme} | {model} | {r['scene']} | " + " | ".join(f"{e:.2e}" for e in r["errors"])
                      + " | " + ", ".join(f"{p:.2f}" for p in r["orders"]) + f" | {r['fitted']:.2f} | "
                      + f"{r['min_eta_reference']:.3f} |"
                      + ("".join(" " + ", ".join(f"{p:.2f}" for p in r[k]) + " |" for k in ("orders_landing", "orders_at_T"))
                         if args.example1 else ""), flush=True)
    out = Path(__file__).with_name("out")
    out.mkdir(exist_ok=True)
    (out / "conv_nonlinear.json").write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
