"""What the command line prints: `stringcontact show`'s scene file (`show_scene`), `stringcontact models`' list
(`show_models`) and a run's closing lines (`report`)."""

from __future__ import annotations

import warnings

from ..errors import one_line
from ..scene.names import DEFAULT_MODEL, DEFAULT_SCHEME

__all__ = ["report", "show_models", "show_scene"]

#: `show`'s line for an optional key the scene does not give.
_NOT_GIVEN = {
    "eps": "scheme projection does not read it; a penalty scheme (--scheme paper, newmark) needs it",
    "load": "no external load (f = 0); a model that reads a load (loaded_obstacle) takes one",
    "obstacle": "the flat obstacle psi = 0 (the paper's y = 0)",
    "petsc_options": "the scheme's own linear solver",
    "restitution": "0: inelastic contact (scheme projection takes e in [0, 1])",
}


def show_scene(scene) -> str:
    """`stringcontact show`: the scene as a TOML file with every key it sets, its scheme and model written out (the
    defaults when it names none), the model's ``[parameters]``, and a comment for each optional key it does not give
    (a ``load = "0"`` would be refused by a model that reads no load): the output loads again as the same run."""
    import tomli_w

    from ..model.registry import load_model
    from ..scene.toml import scene_to_toml
    from ..timestepping import scheme_class

    data = scene.as_dict()
    options = data.pop("petsc_options", None)
    data.pop("parameters", None)
    data.setdefault("model", DEFAULT_MODEL)
    name = scene.scheme or DEFAULT_SCHEME
    if isinstance(data.get("scheme"), dict):  # the [scheme] table, its name first, after the keys
        table = {"scheme": {"name": name} | {k: v for k, v in data.pop("scheme").items() if k != "name"}}
    else:
        data["scheme"], table = name, None
    header = scene_to_toml(scene, penalty=bool(scheme_class(name).PENALTIES)).split("\n", 1)[0] + "\n"  # dt, dx, r
    lines = [header, tomli_w.dumps(data, multiline_strings=True)]
    lines += [f"# {key}: not given: {what}\n" for key, what in _NOT_GIVEN.items() if getattr(scene, key) in (None, ())]
    lines += [tomli_w.dumps(table)] if table is not None else []
    given, constants = dict(scene.parameters), load_model(data["model"]).constants
    if constants or given:
        lines.append(f"\n[parameters]  # the constants of model {data['model']} (`stringcontact models`)\n")
    for c in constants:  # each with its value (the scene's, else its default), unit, range and meaning
        value = given.pop(c.name, c.default)
        about = "; ".join(part for part in (c.description, f"unit {c.unit}" if c.unit else "", f"allowed: {c.allowed}",
                                            "" if c.name in scene.parameters else f"default {c.default_text}") if part)
        lines.append(f"# {c.name}: not given ({one_line(about)})\n" if value is None else
                     f"{tomli_w.dumps({c.name: value}).strip():24s}# {one_line(about)}\n")
    for name, value in given.items():  # kept for the model a run names itself (--model package.module:name)
        lines.append(f"{tomli_w.dumps({name: value}).strip():24s}# not a constant of model {data['model']}: for the "
                     "model given with --model\n")
    return "".join(lines) + (tomli_w.dumps({"petsc_options": options}) if options else "")


def show_models() -> str:
    """`stringcontact models`: each model registered under `scene.names.GROUP` (a scene's `model` key may name it):
    its name, description, where it comes from, its constants and output fields."""
    from ..errors import SceneError
    from ..model.interface import output_fields
    from ..model.registry import load_model
    from ..scene.names import package_of, registered

    text = []
    for name, eps in registered().items():
        try:
            model = load_model(name)
        except SceneError as exc:
            model, lines = None, [f"(unavailable: {exc})"]
        else:
            lines = [model.description]
        lines.append(", ".join(f"{ep.value} [{package_of(ep)}]" for ep in eps))
        if model is not None:
            lines += [f"[parameters] {c.name} = {c.default_text}: {c.allowed}" + (f" [{c.unit}]" if c.unit else "")
                      + (f", {c.description}" if c.description else "") for c in model.constants]
            lines += [f"field {f.name}: {f.title}" for f in output_fields(model)]
        text += [f"{name if i == 0 else '':16s} {line}\n" for i, line in enumerate(lines)]
    return "".join(text)


def _fmt_energy_line(res) -> str:
    from ..run.checks import checks_of

    b = checks_of(res)["energy_balance"]
    external = f" - external work {b['external_work']:.6g}" if b["external_work"] else ""
    internal = b.get("internal_dissipation", 0.0)
    internal = f" + internal variables {internal:.6g}" if internal else ""
    verdict = "closes" if b["closes"] else f"DOES NOT CLOSE (tolerance {b['tolerance']:.0e})"
    return (f"energy balance: E(0) = {b['initial']:.6g} = E(t={res.t[-1]:.4g}) {b['final']:.6g} + viscous "
            f"{b['viscous_dissipation']:.6g}{internal} + contact {b['contact_dissipation']:.6g} + numerical "
            f"{b['numerical_dissipation']:.6g}{external}; residual {b['max_abs_residual']:.2e} "
            f"({b['relative_residual']:.1e} relative): {verdict}")


def _fmt_numerical_line(res) -> str | None:
    """A note when the scheme's own dissipation D_num is over `NUMERICAL_SHARE` of the energy, with what to change."""
    from ..run.checks import NUMERICAL_SHARE, checks_of

    b = checks_of(res)["energy_balance"]
    share = b.get("numerical_share", 0.0)
    if not share > NUMERICAL_SHARE:
        return None
    advice = ("; scheme newmark has no dissipation of its own on a linear model" if res.scheme == "paper"
              and _runs_with(res, "newmark") else "")
    return (f"note: the scheme's own numerical dissipation {b['numerical_dissipation']:.4g} is {100 * share:.0f} % of "
            f"the energy {b['energy_scale']:.6g} (over {100 * NUMERICAL_SHARE:.0f} %): the balance closes, but the "
            f"dissipations are that far from the equation's. Whether it falls with dt is measured by a run at --nt 2x "
            f"(or `stringcontact check`): a time error halves, a dissipation of the model that its residual and stored "
            f"energy do not show stays{advice}")


def _runs_with(res, scheme: str) -> bool:
    """Whether `scheme` runs the run's model (`timestepping.check_model`), which the closing lines advise only then;
    False when the model cannot be loaded again by its name."""
    from ..model.registry import load_model
    from ..timestepping import check_model

    origin = getattr(res, "model_origin", None) or {}
    if origin.get("source") == "object":
        return False
    try:
        check_model(scheme, load_model(origin.get("spec") or res.model))
    except Exception:  # noqa: BLE001 - no advice rather than a failed report
        return False
    return True


def _fmt_penetration_line(res) -> tuple[str, bool]:
    """The penetration line and whether the depth is within its bound (or explained, or has no bound)."""
    from ..run.checks import PENETRATION_FACTOR, PRESS_SPAN, checks_of

    p = checks_of(res)["penetration"]
    if p.get("bound_kind") == "pressed":  # a sustained press: the depth is the penalty's creep, no impact bound
        projection = ", or scheme projection," if _runs_with(res, "projection") else ""
        return (f"penetration: max depth {p['depth']:.4g}: the string is pressed on the obstacle (a contact force "
                f"{p['press_force']:.4g} at a node, held for {p['press_time']:.4g}, over {PRESS_SPAN:g} eps), where a "
                f"velocity penalty lets it creep in at eps x the force: eps x the force's integral over time = "
                f"{p['creep']:.4g}; this is O(eps) (a smaller eps{projection} holds the string out), and "
                f"the impact bound {PENETRATION_FACTOR:g}(eps + dt) max|v| does not apply"), True
    if p["bound"] is None:  # the model's contact law has no known bound: the depth alone, no verdict
        return f"penetration: max depth {p['depth']:.4g} ({p['law']})", True
    start = f"{p['initial_depth']:.4g} (start) + " if p["initial_depth"] > 0 else ""
    line = f"penetration: max depth {p['depth']:.4g} {'within' if p['within_bound'] else 'EXCEEDS'} the bound {start}"
    if p.get("eps_free"):  # a contact step (scheme projection): no eps in the bound
        return f"{line}{PENETRATION_FACTOR:g} dt max|v| = {p['bound']:.4g}", p["within_bound"]
    return (f"{line}{PENETRATION_FACTOR:g}(eps + dt) max|v| = {p['bound']:.4g} (eps max|v| = {p['eps_times_speed']:.4g})",
            p["within_bound"])


def report(res) -> None:
    """The run's closing lines on stdout: parameters, the least gap η − ψ and height η, the contact set, the energy
    balance and the penetration check; then timings, counts and solvers."""
    from ..errors import PenetrationWarning
    from ..io.tables import most_components

    scene = res.scene
    penalty = f"eps={scene.eps:.4g} r={scene.dt / scene.eps:.3g} penalty={res.penalty}" if res.penalty != "none" else "no penalty"
    if res.penalty != "none" and not getattr(res, "law_reads_eps", True):  # a law of the model's own constants
        penalty = f"penalty={res.penalty} (its contact law reads no eps)"
    grid = f"nx={scene.nx}" if res.dim == 1 else f"{scene.domain} with {len(res.x)} nodes"
    restitution = f" restitution={scene.restitution:g}" if scene.restitution else ""
    print(f"scene {scene.name}: scheme {res.scheme}, {grid} nt={scene.nt} dt={scene.dt:.4g} {penalty} "
          f"mass={res.mass}{restitution}" + (f" ({res.status} at t = {res.t[-1]:.6g})" if res.status != "complete" else ""))
    if len(res.t) == 0:
        return
    if scene.obstacle is None:  # + 0.0: no "-0"
        minima = f"min gap eta - psi = min eta = {res.min_eta + 0.0:.6g} (the obstacle psi = 0)"
    else:
        minima = f"min gap eta - psi = {getattr(res, 'min_gap', float('nan')) + 0.0:.6g} (min eta = {res.min_eta + 0.0:.6g})"
    if res.dim == 1:
        most, several = most_components(res).get("contact_components"), ""
        if most and most["most"] >= 2:  # when contact began, the most components at once and when (Example 2's point)
            began = next(float(t) for t, k in zip(res.t, res.contact_components) if k > 0)
            several = (f"; first contact at t = {began:.4g}; at most {most['most']} contact components at once "
                       f"(first at t = {most['first_at']:.4g})")
        print(f"{minima}; final contact length = {res.contact_length[-1]:.4g}{several}")
    else:
        print(f"{minima}; final contact area = {res.contact_measure[-1]:.4g} in {res.contact_components[-1]} patch(es)")
    line, ok = _fmt_penetration_line(res)
    print("\n".join(text for text in (_fmt_energy_line(res), _fmt_numerical_line(res), line) if text))
    if not ok:
        warnings.warn("the string went further below the obstacle than its contact law allows, with no press to explain "
                      "it; a force the penalty cannot stop holds it down (a model variant, r > 1); see "
                      "docs/explanation/reliability.md", PenetrationWarning)
    if res.timings:
        print("time: " + ", ".join(f"{k} {v:.3g} s" for k, v in res.timings.items()))
    if res.counters:
        print("counts: " + ", ".join(f"{k} {v}" for k, v in res.counters.items()))
    for what, description in res.solver.items():
        print(f"{what}: {description}")
