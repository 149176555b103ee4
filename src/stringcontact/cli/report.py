"""What the command line prints: `stringcontact show`'s scene file (`show_scene`) and a run's closing lines
(`report`). Imported when a command needs it, so that `stringcontact run` starts its picture process first."""

from __future__ import annotations

import warnings

from ..scene.names import DEFAULT_MODEL, DEFAULT_SCHEME

__all__ = ["report", "show_scene"]


#: `show`'s line for an optional key the scene does not give.
_NOT_GIVEN = {
    "load": "no external load (f = 0); a model that reads a load (loaded_obstacle) takes one",
    "obstacle": "the flat obstacle psi = 0 (the paper's y = 0)",
    "petsc_options": "the scheme's own linear solver",
    "restitution": "0: inelastic contact (scheme projection takes e in [0, 1])",
}


def show_scene(scene) -> str:
    """`stringcontact show`: the scene as a TOML scene file with every key it sets, the scheme and model it runs
    with written out (the defaults `paper` and `inelastic` when it names none), and a comment for each optional key
    it does not give (`load`, `obstacle`, `petsc_options`): a load = "0" key would be refused by a model that reads
    no load, so those stay comments and the output loads again as the same run."""
    import tomli_w

    from ..scene.toml import scene_to_toml

    data = scene.as_dict()
    options = data.pop("petsc_options", None)
    data.pop("parameters", None)
    data.setdefault("model", DEFAULT_MODEL)
    data.setdefault("scheme", DEFAULT_SCHEME)
    missing = [f"# {key}: not given: {what}\n" for key, what in _NOT_GIVEN.items() if getattr(scene, key) in (None, ())]
    header = scene_to_toml(scene).split("\n", 1)[0] + "\n"  # its derived values: dt, dx, r
    table = tomli_w.dumps({"petsc_options": options}) if options else ""
    return (header + tomli_w.dumps(data, multiline_strings=True) + "".join(missing)
            + _parameters_table(data["model"], dict(scene.parameters)) + table)


def _parameters_table(model_name: str, given: dict) -> str:
    """The model's constants as a ``[parameters]`` table: each with its value (the scene's, else its default), its
    unit, range and meaning in a comment; an optional constant without a value as a comment line."""
    import tomli_w

    from ..model.registry import load_model

    constants = load_model(model_name).constants
    if not constants:
        return ""
    lines = [f"\n[parameters]  # model {model_name!r}'s constants (`stringcontact models`)\n"]
    for c in constants:
        value = given.get(c.name, c.default)
        about = "; ".join(part for part in (c.description, f"unit {c.unit}" if c.unit else "", f"allowed: {c.allowed}",
                                            "" if c.name in given else f"default {c.default_text}") if part)
        if value is None:
            lines.append(f"# {c.name}: not given ({about})\n")
        else:
            lines.append(f"{tomli_w.dumps({c.name: value}).strip():24s}# {about}\n")
    return "".join(lines)


def _fmt_energy_line(res) -> str:
    from ..run.checks import checks_of

    b = checks_of(res)["energy_balance"]
    external = f" - external work {b['external_work']:.6g}" if b["external_work"] else ""
    verdict = "closes" if b["closes"] else f"DOES NOT CLOSE (tolerance {b['tolerance']:.0e})"
    return (
        f"energy balance: E(0) = {b['initial']:.6g} = E(t={res.t[-1]:.4g}) {b['final']:.6g} + viscous {b['viscous_dissipation']:.6g} "
        f"+ contact {b['contact_dissipation']:.6g} + numerical {b['numerical_dissipation']:.6g}{external}; "
        f"residual {b['max_abs_residual']:.2e} ({b['relative_residual']:.1e} relative): {verdict}"
    )


def _fmt_penetration_line(res) -> tuple[str, bool]:
    from ..run.checks import PENETRATION_FACTOR, checks_of

    p = checks_of(res)["penetration"]
    if p["bound"] is None:  # the model's contact law has no known bound: the depth alone, no verdict
        return f"penetration: max depth {p['depth']:.4g} ({p['law']})", True
    start = f"{p['initial_depth']:.4g} (start) + " if p["initial_depth"] > 0 else ""
    verdict = "within" if p["within_bound"] else "EXCEEDS"
    if p.get("eps_free"):  # a contact step (scheme projection): no eps in the bound
        line = f"penetration: max depth {p['depth']:.4g} {verdict} the bound {start}{PENETRATION_FACTOR:g} dt max|v| = {p['bound']:.4g}"
        return line, p["within_bound"]
    line = (
        f"penetration: max depth {p['depth']:.4g} {verdict} the bound {start}{PENETRATION_FACTOR:g}(eps + dt) max|v| "
        f"= {p['bound']:.4g} (eps max|v| = {p['eps_times_speed']:.4g})"
    )
    return line, p["within_bound"]


def report(res) -> None:
    """The run's closing lines on stdout: parameters, min η, the energy balance and the penetration check."""
    from ..errors import PenetrationWarning

    scene = res.scene
    penalty = (f"eps={scene.eps:.4g} r={scene.dt / scene.eps:.3g} penalty={res.penalty}" if res.penalty != "none"
               else "no penalty")
    grid = f"nx={scene.nx}" if res.dim == 1 else f"{scene.domain} with {len(res.x)} nodes"
    restitution = f" restitution={scene.restitution:g}" if scene.restitution else ""
    print(f"scene {scene.name}: scheme {res.scheme}, {grid} nt={scene.nt} dt={scene.dt:.4g} {penalty} "
          f"mass={res.mass}{restitution}" + (f" ({res.status} at t = {res.t[-1]:.6g})" if res.status != "complete" else ""))
    if len(res.t) == 0:
        return
    if res.dim == 1:
        print(f"min eta = {res.min_eta:.6g}; final contact length = {res.contact_length[-1]:.4g}"
              + _components_note(res))
    else:
        print(f"min eta = {res.min_eta:.6g}; final contact area = {res.contact_measure[-1]:.4g} "
              f"in {res.contact_components[-1]} patch(es)")
    print(_fmt_energy_line(res))
    line, ok = _fmt_penetration_line(res)
    print(line)
    if not ok:
        warnings.warn(
            "the string went further below the obstacle than its contact law allows; a force the penalty "
            "cannot stop holds it down (a static load, a model variant, r > 1); see docs/explanation/reliability.md",
            PenetrationWarning,
        )
    if res.timings:
        print("time: " + ", ".join(f"{k} {v:.3g} s" for k, v in res.timings.items()))
    if res.counters:
        print("counts: " + ", ".join(f"{k} {v}" for k, v in res.counters.items()))
    for what, description in res.solver.items():
        print(f"{what}: {description}")


def _components_note(res) -> str:
    """"; at most K contact components (first at t = ...)": Example 2's point is a contact set of several."""
    from ..io.tables import most_components

    most = most_components(res).get("contact_components")
    if most is None or most["most"] < 2:
        return ""
    return f"; at most {most['most']} contact components (first at t = {most['first_at']:.4g})"
