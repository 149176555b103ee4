"""The generated parts of the reference pages, docs/reference/*.md: MyST markdown made from the code, committed so
that the pages read in the repository as on the site.

Each part sits between its markers in its page (``<!-- generated: NAME ... -->`` and ``<!-- end of the generated
part -->``); `write_all` makes them again (`make reference`, and the site's build), and tests/docs/test_reference.py
fails when a committed page differs from what the code makes. Each table is made from the definitions the program
itself uses, so a page cannot drift from the code:

* `scene_keys`: `scene.limits` (FILE_KEYS, KEY_DOCS, DOMAIN_KEYS) and `scene.checks.allowed`, the text of the
  error messages;
* `models`: the constants (a scene's ``[parameters]``) and output fields of every model this package registers,
  from the models themselves (`Model.constants`, `Model.outputs`; `ModelConstant.allowed` is the error messages'
  text);
* `cli`: the argparse parsers of `stringcontact.cli.parser.build_parser`;
* `exit_codes`: the exit-code list in `stringcontact.cli.main`'s docstring and its `EXIT_*` constants;
* `output_files`: `io.tables.DIAGNOSTIC_COLUMNS`, `io.result.FIELDS`/`ENERGY_KEYS`, `plot.run_pictures`'s pictures,
  and what a run writes of its model's output fields (`MODEL_FIELD_FILES`);
* `api`: every name of `stringcontact.__all__` and of the public modules (`PUBLIC_MODULES`) with its signature (the
  defaults as the source writes them) and its docstring, in markdown.

A name the code adds without a description here (a scene key, a CSV column, a field) is an error, which fails
the build: `tests/docs/test_reference.py` checks the same.
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import importlib
import inspect
import re
import textwrap
from pathlib import Path

#: The modules a user touches besides the top-level namespace, what the API reference documents: module ->
#: (title, the public names; None: its `__all__`).
PUBLIC_MODULES = {
    "stringcontact.core.problem": ("The core: a model on your own mesh and Functions", ("ContactProblem",)),
    "stringcontact.core.stepper": ("The core: the time stepper you loop over", ("TimeStepper",)),
    "stringcontact.core.ledger": ("The energy ledger", ("EnergyLedger",)),
    "stringcontact.core.observers": ("What watches the steps", ("Observer",)),
    "stringcontact.run.rows": ("The stored rows, an observer", ("RowObserver",)),
    "stringcontact.model.interface": ("The model contract: what a model is and declares", None),
    "stringcontact.model.inelastic": ("The paper's model in UFL, what a model variant reuses or replaces", None),
    "stringcontact.model.variants": ("The model variants shipped with the package", None),
    "stringcontact.run.options": ("The options of simulate", None),
    "stringcontact.timestepping.implicit": ("A time scheme from its difference quotients", ("ImplicitScheme",)),
    "stringcontact.timestepping.base": ("The time-scheme contract",
                                        ("Scheme", "SchemeOption", "StepEnergy", "DiscreteProblem", "NodalLaws",
                                         "MovingObstacle")),
    "stringcontact.fem.operators": ("The operators a scheme steps with", ("Operators", "NonlinearForm")),
    "stringcontact.io.result": ("A run's result", ("Result",)),
    "stringcontact.scene": ("Scenes", None),
    "stringcontact.errors": ("Errors", ("SolverError", "OutputError", "Interrupted", "PenetrationWarning", "one_line")),
}

#: diagnostics.csv's columns (io.tables.DIAGNOSTIC_COLUMNS).
COLUMNS = {
    "step": "the time step of the row (0 … nt)",
    "t": "the time",
    "kinetic": "kinetic energy ½∫η_t²",
    "elastic": "elastic energy ½∫|∇η|² (the model's)",
    "viscous_dissipation": "viscous dissipation α∫∫|∇η_t|² up to t (cumulative)",
    "contact_dissipation": "energy taken by the contact force up to t (cumulative)",
    "numerical_dissipation": "energy taken by the scheme itself up to t (cumulative)",
    "external_work": "work of an external load up to t (cumulative; 0 without a load)",
    "internal_dissipation": ("energy taken by the model's internal variables (a field whose rate enters the "
                             "residual: a dashpot) up to t (cumulative; 0 without them)"),
    "balance_residual": "E(0) − [E(t) + dissipations − external work]: closes to round-off",
    "min_eta": "min over the nodes of the height η at the row (η itself, whatever the obstacle; summary.json's `min_eta`: over every step)",
    "min_gap": "min over the nodes of the gap η − ψ at the row, ψ at the row's time (below 0: below the obstacle, that deep; ψ = 0 without an obstacle, where it is `min_eta`; summary.json's `min_gap`: over every step)",
    "contact_length": "the length of the contact set {η ≤ ψ}; a membrane's file names this column `contact_area`, its area",
    "contact_components": "the number of contact intervals (2D: patches)",
    "max_contact_force": "the largest nodal contact force",
}
#: The fields of solution.xdmf at each stored time (io.result.FIELDS).
FIELDS = {
    "eta": "the displacement η",
    "velocity": "the velocity η_t",
    "contact": "1 where η ≤ ψ (on or below the obstacle), else 0",
    "contact_force": "the nodal contact force F",
}
#: The fields written only by some runs (io.result.OBSTACLE_FIELD): after the fields above.
SOME_FIELDS = {
    "obstacle": "a moving obstacle only (ψ an expression in t): ψ at the nodes at the frame's time; the gap is "
                "η − ψ (ParaView's Calculator: `eta-obstacle`). An obstacle at rest is not written",
}
#: What a run writes of each of its model's output fields (`Model.outputs`; io.tables, plot.run_pictures): where -> what.
MODEL_FIELD_FILES = {
    "solution.xdmf": "`NAME`: the field at the nodes, at each written time",
    "rows.npz": "`NAME`: the field's stored rows (`field_NAME` where NAME is one of the file's own arrays)",
    "diagnostics.csv": "`min_NAME`, `max_NAME`: the field's least and largest value over the nodes, after the "
                       "columns below (`field_NAME` where those are core columns)",
    "summary.json": "`fields`: how each field is shown (label, unit, colours, scale); `parameters`: the model's "
                    "constants as the run used them",
    "NAME.png": "a string's field over (x, t) with the contact set outlined, a membrane's at the stored time of its "
                "largest |value|, beside the field's least and largest value against t (`field_NAME.png` where "
                "NAME.png is one of the pictures below)",
}
#: The pictures of a run (plot.run_pictures): 1D and 2D.
PICTURES = {
    "contact_set.png": "the space-time contact set {η ≤ ψ}",
    "velocity_field.png": "the velocity η_t over (x, t)",
    "snapshots.png": "η at the scene's output times, contact in red",
    "energy.png": "the energies and dissipations over time (the balance)",
    "space_time.png": "η(x, t) as a surface, red where in contact",
    "membrane.png": "the membrane warped by η at the output times, red where it touches",
    "contact_area.png": "the contact area over time",
    "membrane.gif": "the membrane's animation",
}
#: The files of an output folder that are not pictures.
FILES = {
    "solution.xdmf": "the mesh once and, at up to `--frames` stored times, one grid carrying every field below "
                     "(ParaView, meshio)",
    "solution.h5": "the XDMF's heavy data (HDF5)",
    "diagnostics.csv": "one row per stored time: the columns below",
    "summary.json": "parameters, versions, timings, checks, `status` (complete, unstable, unbalanced, interrupted)",
    "rows.npz": "the stored rows the pictures are drawn from (`numpy.load`; `stringcontact plot` redraws from it)",
    "view.py": "ParaView's view of this run: `paraview --script=view.py`",
    "manifest.json": "the names and sizes of the files the command wrote (all that `--force` may replace)",
}


def _cell(text) -> str:
    """`text` for a markdown table cell: one line, backslashes and pipes escaped."""
    return " ".join(str(text).split()).replace("\\", "\\\\").replace("|", "\\|")


def _table(header: list[str], rows: list[list]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + " --- |" * len(header)]
    lines += ["| " + " | ".join(_cell(c) for c in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def _undocumented(what: str, names, documented) -> None:
    missing = [n for n in names if n not in documented]
    if missing:
        raise RuntimeError(f"{what} without a description in docs/_ext/reference_pages.py: {', '.join(missing)}")


def scene_keys() -> str:
    """The table of every scene key: type, unit, default, allowed values (the error messages' text), 1D/2D."""
    from stringcontact.scene import checks, limits

    _undocumented("scene keys (scene/limits.py KEY_DOCS)", limits.FILE_KEYS, limits.KEY_DOCS)
    domains = {key: name for name, keys in limits.DOMAIN_KEYS.items() for key in keys}
    rows = []
    for key in limits.FILE_KEYS:
        kind, unit, default, meaning = limits.KEY_DOCS[key]
        domain = domains.get(key)
        where = "1D" if domain == "interval" else f"2D ({domain})" if domain else "1D, 2D"
        if key in limits.REQUIRED_KEYS and not default.startswith("required"):  # eps says when it is required
            default = "required" + (" (1D)" if domain == "interval" else "")
        rows.append([f"`{key}`", meaning, kind, unit or "–", default, checks.allowed(key), where])
    from stringcontact.scene import expressions

    language = (f"An expression is at most {expressions.MAX_LENGTH} characters: "
                f"{expressions._ALLOWED_TEXT} (`where(cond, a, b)`; `piecewise(c1, v1, c2, v2, ..., default)`: the first true condition wins). "
                "`x` (and `y` in 2D) is the point, `l` the length, `h` the end height when the scene gives one.\n")
    return _table(["key", "meaning", "type", "unit", "default", "allowed", "domain"], rows) + "\n" + language


def shipped_models() -> dict:
    """The models this package registers (their entry point's package is stringcontact), loaded: name -> Model.
    A plugin's models (another package's entry points) are not part of this site."""
    from stringcontact.model.registry import load_model
    from stringcontact.scene.names import package_of, registered

    return {name: load_model(name) for name, eps in registered().items() if package_of(eps[0]) == "stringcontact"}


def models() -> str:
    """Every shipped model's constants (name, default, allowed range, unit, meaning) and output fields (name,
    label, unit, what they are), and the models that have none."""
    from stringcontact.model.interface import output_fields

    shipped = shipped_models()
    constants, fields = [], []
    for name, model in shipped.items():
        for c in model.constants:
            constants.append([f"`{c.name}`", f"`{name}`", c.default_text, c.allowed, c.unit or "–", c.description])
        unknowns = set(getattr(model, "fields", ()))
        for f in output_fields(model):
            what = "derived from the unknowns" if f.expression is not None else (
                "an unknown of the model" if f.name in unknowns else "")
            fields.append([f"`{f.name}`", f"`{name}`", f.label or f.name, f.unit or "–", what])
    without = [f"`{n}`" for n, m in shipped.items() if not m.constants]
    silent = [f"`{n}`" for n, m in shipped.items() if not output_fields(m)]
    out = ["### Constants\n",
           "A scene gives them in its `[parameters]` table; a constant not given takes its default (\"required\": the "
           "scene must give it; \"none\": the feature is off). A name the model does not declare, or a value outside "
           "*allowed* (the text of the error message), is refused in one line.\n",
           _table(["constant", "model", "default", "allowed", "unit", "meaning"], constants)]
    if without:
        out.append(f"Without constants: {', '.join(without)}.\n")
    out += ["### Output fields\n",
            "Besides `eta`, `velocity`, `contact` and `contact_force`, each run writes its model's output fields: "
            "`Result.fields[name]`, `rows.npz`, `solution.xdmf` and the picture `NAME.png`.\n",
            _table(["field", "model", "label", "unit", "what"], fields)]
    if silent:
        out.append(f"Without output fields: {', '.join(silent)}.\n")
    return "\n".join(out)


def _walk(parser: argparse.ArgumentParser, prog: str, help_text: str, level: int) -> list[str]:
    out = [f"{'#' * level} `{prog}`\n", f"{help_text}\n" if help_text else "", "```text", parser.format_usage().strip(),
           "```\n"]
    rows, children = [], []
    for action in parser._actions:
        if isinstance(action, argparse._HelpAction) or action.help == argparse.SUPPRESS:
            continue
        if isinstance(action, argparse._SubParsersAction):
            helps = {a.dest: a.help for a in action._choices_actions}
            children += [(name, sub, helps.get(name, "")) for name, sub in action.choices.items()]
            continue
        name = ", ".join(f"`{o}`" for o in action.option_strings) or f"`{action.dest}`"
        value = ""
        if action.choices:
            value = ", ".join(f"`{c}`" for c in action.choices)
        elif action.nargs != 0:
            value = f"`{action.metavar or action.dest.upper()}`" if action.option_strings else ""
            if action.type is not None:
                value += f" ({getattr(action.type, '__name__', action.type)})"
        default = "" if action.default in (None, False, [], argparse.SUPPRESS) else f"`{action.default}`"
        rows.append([name, value, default, action.help or ""])
    if rows:
        out.append(_table(["argument", "value", "default", "meaning"], rows))
    for name, sub, text in children:
        out += _walk(sub, f"{prog} {name}", text, min(level + 1, 6))
    return out


#: the width the usage lines are wrapped at (argparse's is the terminal's: the committed page must not depend on it)
USAGE_WIDTH = 100


def cli() -> str:
    """Every subcommand of `stringcontact`: usage and arguments, from the parsers the command line builds."""
    import os
    from unittest import mock

    from stringcontact.cli.parser import SUBCOMMANDS, build_parser

    parser = build_parser(["run", "list", "show", *SUBCOMMANDS])  # every subcommand with its arguments
    with mock.patch.dict(os.environ, {"COLUMNS": str(USAGE_WIDTH)}):  # argparse wraps the usage at the terminal's
        return "\n".join(_walk(parser, "stringcontact", parser.description, 1)[5:])  # the page has its own title


def exit_codes() -> str:
    """The exit codes as the command line's docstring lists them, checked against its constants."""
    from stringcontact.cli import main

    text = main.__doc__.split("Exit codes:", 1)[1]
    items = re.findall(r"^\* (\d+(?:, \d+)*|\d+) (.*?)(?=^\* |^\S|\Z)", text, re.DOTALL | re.MULTILINE)
    rows = [[f"`{code}`", " ".join(what.split()).rstrip(";.")] for code, what in items]
    codes = {c for code, _ in items for c in re.findall(r"\d+", code)}
    constants = {str(v) for k, v in vars(main).items() if k.startswith("EXIT_")}
    _undocumented("exit codes (cli/process.py EXIT_*)", sorted(constants), codes)
    return _table(["exit code", "meaning"], rows)


def output_files() -> str:
    """The output folder's files, solution.xdmf's fields, diagnostics.csv's columns, the pictures."""
    from stringcontact.io.result import FIELDS as fields
    from stringcontact.io.result import OBSTACLE_FIELD
    from stringcontact.io.tables import DIAGNOSTIC_COLUMNS
    from stringcontact.plot.run_pictures import MEMBRANE_PICTURES
    from stringcontact.plot.run_pictures import PICTURES as pictures

    _undocumented("diagnostics.csv columns (io/tables.py)", DIAGNOSTIC_COLUMNS, COLUMNS)
    _undocumented("XDMF fields (io/result.py FIELDS)", fields, FIELDS)
    _undocumented("XDMF fields of some runs (io/result.py OBSTACLE_FIELD)", [OBSTACLE_FIELD], SOME_FIELDS)
    _undocumented("pictures (plot/run_pictures.py)", dict.fromkeys(pictures + MEMBRANE_PICTURES), PICTURES)
    shown = {name: ("1D" if name in pictures else "") + (", " if name in pictures and name in MEMBRANE_PICTURES else "")
             + ("2D" if name in MEMBRANE_PICTURES else "") for name in dict.fromkeys(pictures + MEMBRANE_PICTURES)}
    return "\n".join([
        "## Files\n", _table(["file", "what it holds"], [[f"`{k}`", v] for k, v in FILES.items()]),
        "## A model's output fields\n",
        "Each field a model declares (`Model.outputs`, and each of its further unknowns; `stringcontact models` lists "
        "them, the scene-keys page those of the shipped models), under its name `NAME`:\n",
        _table(["file", "what it holds of the field"], [[f"`{k}`", v] for k, v in MODEL_FIELD_FILES.items()]),
        "## Fields of `solution.xdmf`\n",
        _table(["field", "meaning"], [[f"`{k}`", FIELDS[k]] for k in fields]
               + [[f"`{k}`", SOME_FIELDS[k]] for k in [OBSTACLE_FIELD]]),
        "## Columns of `diagnostics.csv`\n",
        _table(["column", "meaning"], [[f"`{k}`", COLUMNS[k]] for k in DIAGNOSTIC_COLUMNS]),
        "## Pictures\n",
        _table(["picture", "what it shows", "runs"], [[f"`{k}`", PICTURES[k], shown[k]] for k in shown]),
    ])


def public_names(module_name: str) -> list[str]:
    """The public names of a public module (`PUBLIC_MODULES`): the names listed there, else its `__all__`."""
    names = PUBLIC_MODULES.get(module_name, ("", None))[1]
    return list(names if names is not None else importlib.import_module(module_name).__all__)


def _source_defaults(obj) -> dict[str, str]:
    """The default values of `obj`'s parameters as its source writes them (``comm=MPI.COMM_WORLD``, not the object's
    repr with its address, which would change the page at every run): a function's, or a dataclass's fields'."""
    try:
        node = ast.parse(textwrap.dedent(inspect.getsource(obj))).body[0]
    except (OSError, TypeError, SyntaxError, IndexError):
        return {}
    if isinstance(node, ast.ClassDef):
        return {n.target.id: ast.unparse(n.value) for n in node.body
                if isinstance(n, ast.AnnAssign) and isinstance(n.target, ast.Name) and n.value is not None}
    if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
        return {}
    args = node.args
    positional = args.posonlyargs + args.args
    found = {a.arg: ast.unparse(d) for a, d in zip(positional[len(positional) - len(args.defaults):], args.defaults)}
    return found | {a.arg: ast.unparse(d) for a, d in zip(args.kwonlyargs, args.kw_defaults) if d is not None}


def signature(name: str, obj) -> str:
    """``name(parameters) -> return``: the signature of the function or class `obj` with the annotations and defaults
    as the source writes them, one parameter a line when it is longer than `SIGNATURE_WIDTH`."""
    callee = obj.__init__ if isinstance(obj, type) and not dataclasses.is_dataclass(obj) else obj
    if isinstance(obj, type) and next(k for k in obj.__mro__ if "__init__" in vars(k)).__module__ == "builtins":
        return f"class {name}({', '.join(base.__name__ for base in obj.__bases__)})"  # an exception or a warning
    try:
        sig = inspect.signature(obj)
    except (TypeError, ValueError):
        return f"{name}(...)"
    defaults = _source_defaults(obj if dataclasses.is_dataclass(obj) else callee)
    parts, star = [], False
    for param in sig.parameters.values():
        if param.name in ("self", "cls") and not parts:
            continue
        if param.kind is param.KEYWORD_ONLY and not star:
            parts.append("*")
            star = True
        text = {param.VAR_POSITIONAL: "*", param.VAR_KEYWORD: "**"}.get(param.kind, "") + param.name
        star = star or param.kind is param.VAR_POSITIONAL
        if param.annotation is not param.empty:
            text += f": {_annotation(param.annotation)}"
        if param.default is not param.empty:
            default = defaults.get(param.name, repr(param.default))
            text += (" = " if param.annotation is not param.empty else "=") + default
        parts.append(text)
        if param.kind is param.POSITIONAL_ONLY and _last_positional(sig, param):
            parts.append("/")
    returns = "" if sig.return_annotation is sig.empty or isinstance(obj, type) else f" -> {_annotation(sig.return_annotation)}"
    line = f"{name}({', '.join(parts)}){returns}"
    if len(line) <= SIGNATURE_WIDTH:
        return line
    return f"{name}(\n" + "".join(f"    {part},\n" for part in parts) + f"){returns}"


def _annotation(annotation) -> str:
    """An annotation as the source writes it (they are strings: ``from __future__ import annotations``)."""
    return annotation if isinstance(annotation, str) else inspect.formatannotation(annotation)


def _last_positional(sig, param) -> bool:
    kinds = [p.kind for p in sig.parameters.values()]
    index = list(sig.parameters).index(param.name)
    return param.kind is param.POSITIONAL_ONLY and (index + 1 == len(kinds) or kinds[index + 1] is not param.POSITIONAL_ONLY)


#: the widest signature on one line; a longer one is written a parameter a line
SIGNATURE_WIDTH = 100
_ROLE = re.compile(r":[a-z]+:`~?([^`]+)`")


def markdown(doc: str | None) -> str:
    """A docstring as markdown: its reStructuredText roles and double backquotes as code, its literal blocks
    (``Usage::`` and the indented lines after it) fenced, as Python where they parse as Python, else as text."""
    lines = inspect.cleandoc(doc or "").replace("``", "`").splitlines()
    out, block = [], None
    for line in [*lines, "."]:  # a last line that ends a block
        line = _ROLE.sub(lambda m: f"`{m.group(1)}`", line)
        if block is not None:
            if not line.strip() or line.startswith(" "):
                block.append(line[4:] if line.strip() else "")
                continue
            out += _fenced(block)
            block = None
        if line.rstrip().endswith("::"):
            out.append(line.rstrip()[:-1] if line.strip() != "::" else "")
            block = []
            continue
        out.append(line)
    out.pop()  # the "." that ended the last block
    while out and not out[-1].strip():
        out.pop()
    return "\n".join(out) + "\n"


def _fenced(block: list[str]) -> list[str]:
    """The lines of a literal block fenced: as Python if they parse as Python, else as text; a blank line after."""
    while block and not block[0].strip():
        block.pop(0)
    while block and not block[-1].strip():
        block.pop()
    try:
        ast.parse("\n".join(block))
        language = "python"
    except SyntaxError:
        language = "text"
    return ["", f"```{language}", *block, "```", ""]


def _members(cls) -> list[tuple[str, object]]:
    """The public methods and properties `cls` defines itself, in source order; a dataclass's fields are in its
    docstring."""
    fields = {f.name for f in dataclasses.fields(cls)} if dataclasses.is_dataclass(cls) else set()
    return [(attr, member) for attr, member in vars(cls).items() if not attr.startswith("_") and attr not in fields
            and (inspect.isfunction(member) or isinstance(member, (property, classmethod, staticmethod)))]


def entry(qualified: str, obj, level: int = 3) -> str:
    """The API page's entry of `obj`: a heading with its name, its signature (a function or class) or value (data),
    and its docstring; a class's public methods and properties after it, one level down."""
    name = qualified.rsplit(".", 1)[1]
    heading = "#" * level + f" `{name}`\n"
    if isinstance(obj, type) or (callable(obj) and not hasattr(obj, "momentum_form")):
        kind = "class" if isinstance(obj, type) else "function"
        doc = obj.__dict__.get("__doc__") if isinstance(obj, type) else obj.__doc__
        out = [heading, f"{kind} `{qualified}`\n", f"```python\n{signature(name, obj)}\n```\n", markdown(doc)]
        if isinstance(obj, type):
            for attr, member in _members(obj):
                function = member.__func__ if isinstance(member, (classmethod, staticmethod)) else member
                what = "property" if isinstance(member, property) else "classmethod" if isinstance(member, classmethod) \
                    else "method"
                out.append("#" * (level + 1) + f" `{name}.{attr}`\n")
                if isinstance(member, property):
                    out.append(f"{what}\n")
                    function = member.fget
                else:
                    out.append(f"{what}\n\n```python\n{signature(attr, function)}\n```\n")
                out.append(markdown(function.__doc__))
        return "\n".join(out)
    doc = data_doc(name, obj)
    if doc is None:
        raise RuntimeError(f"{qualified}: no #: comment where it is defined")
    value = repr(obj)
    plain = isinstance(obj, (int, float, str, tuple)) and (not isinstance(obj, tuple) or all(  # the value, not a
        isinstance(v, (int, float, str)) for v in obj))  # repr that depends on what is installed (SCHEMES)
    shown = f"{name} = {value}" if plain and len(value) <= SIGNATURE_WIDTH else f"{name}: {type(obj).__name__}"
    return "\n".join([heading, f"data `{qualified}`\n", f"```python\n{shown}\n```\n", markdown("\n".join(doc))])


def data_doc(attr: str, obj) -> list[str] | None:
    """The `#:` comment lines of `attr` in the stringcontact module where it is `obj` and has them, or None."""
    import sys

    from sphinx.pycode import ModuleAnalyzer

    for name, module in sorted(sys.modules.items()):
        if not name.startswith("stringcontact") or module is None:
            continue
        if getattr(module, attr, None) is obj:
            docs = ModuleAnalyzer.for_module(name).find_attr_docs().get(("", attr))
            if docs and any(line.strip() for line in docs):
                return [line for line in docs if line.strip()]
    return None


def api() -> str:
    """Every public name with its signature and docstring: `stringcontact.__all__` first, then each public module's
    other public names (its docstring first)."""
    import stringcontact

    out = ["## `stringcontact`\n"]
    top = {id(getattr(stringcontact, name)) for name in stringcontact.__all__}
    out += [entry(f"stringcontact.{name}", getattr(stringcontact, name)) for name in stringcontact.__all__]
    for module_name, (title, _) in PUBLIC_MODULES.items():
        module = importlib.import_module(module_name)
        rest = [n for n in public_names(module_name) if id(getattr(module, n)) not in top]
        if not rest:
            continue
        out += [f"## {title}: `{module_name}`\n", markdown(module.__doc__)]
        out += [entry(f"{module_name}.{n}", getattr(module, n)) for n in rest]
    return "\n".join(out)


PARTS = {"scene_keys": scene_keys, "models": models, "cli": cli, "exit_codes": exit_codes, "output_files": output_files,
         "api": api}
#: the committed reference pages (docs/reference/NAME.md) and the generated parts each holds, in order
PAGES = {"api": ("api",), "cli": ("cli",), "scene_keys": ("scene_keys", "models"), "output": ("output_files",),
         "exit_codes": ("exit_codes",)}
_PART = re.compile(r"(<!-- generated: (\w+) [^\n]*-->\n)(.*?)(<!-- end of the generated part -->)", re.DOTALL)


def page_text(text: str) -> str:
    """A reference page's `text` with each generated part (between its markers) made again from the code."""
    return _PART.sub(lambda m: m.group(1) + "\n" + PARTS[m.group(2)]().rstrip("\n") + "\n\n" + m.group(4), text)


def stale(folder: Path) -> list[str]:
    """The pages in `folder` (docs/reference) whose generated parts differ from what the code makes now."""
    return [name for name in PAGES if (folder / f"{name}.md").read_text() != page_text((folder / f"{name}.md").read_text())]


def write_all(folder: Path) -> list[Path]:
    """Make the generated parts of the reference pages in `folder` (docs/reference) again, writing a page only
    when its text changed (so Sphinx rereads only those). `make reference` runs it; so does the site's build."""
    written = []
    for name, parts in PAGES.items():
        path = folder / f"{name}.md"
        text = path.read_text()
        found = [m.group(2) for m in _PART.finditer(text)]
        if found != list(parts):
            raise RuntimeError(f"{path}: generated parts {found}, expected {list(parts)} (their markers: "
                               "<!-- generated: NAME ... --> and <!-- end of the generated part -->)")
        new = page_text(text)
        if new != text:
            path.write_text(new)
        written.append(path)
    return written


if __name__ == "__main__":  # `make reference`: docs/reference's generated parts from the code
    for path in write_all(Path(__file__).resolve().parents[1] / "reference"):
        print(f"reference: {path}")
