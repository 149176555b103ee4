"""What a model declares is refused in one line naming it when a run could not write or read it back: output fields
whose names collide in the files, descriptions `plot` would refuse, fields that are not finite, declarations of the
wrong kind; `stringcontact show` keeps the scene's [parameters] and writes valid TOML."""

import dataclasses
import tomllib
import warnings

import pytest
import ufl

import stringcontact as sc
from stringcontact.model.forms import FormError
from stringcontact.scene.parameters import ModelConstant

SCENE = dict(nx=30, T=0.002, dt=0.0005, output_times=[])


def run(model, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return sc.simulate(sc.load_scene("example1").replace(**SCENE), model=model, **kwargs)


def with_outputs(*fields):
    return dataclasses.replace(sc.inelastic, name="declares", outputs=fields)



@pytest.mark.parametrize("names", [("steps", "reaction"), ("gap",), ("energy",), ("field_steps",), ("membrane",),
                                   ("reaction", "reaction")])
def test_output_field_names_that_collide_in_the_files_are_refused_before_the_mesh(names):
    model = with_outputs(*(sc.OutputField(n, expression=lambda U, p: U[0] ** 2) for n in names))
    fragment = "twice" if len(set(names)) < len(names) else "a name the run's files use themselves"
    with pytest.raises(FormError, match=f"model 'declares': outputs name '{names[0]}' {fragment}"):
        run(model)


@pytest.mark.parametrize(("given", "fragment"), [
    ({"label": None}, "label must be text of at most 200 characters"),
    ({"label": "x" * 201}, "label must be text of at most 200 characters"),
    ({"unit": 3}, "unit must be text"),
    ({"symmetric": "yes"}, "symmetric and surface must be True or False"),
])
def test_an_output_field_plot_could_not_read_back_is_refused_when_made(given, fragment):
    with pytest.raises(ValueError, match=fragment):
        sc.OutputField("q", **given)


def test_an_output_fields_name_fits_a_file_name():
    sc.OutputField("q" * 60)
    with pytest.raises(ValueError, match="an identifier of at most 60 characters"):
        sc.OutputField("q" * 61)


@pytest.mark.parametrize(("expression", "fragment"), [
    (lambda U, p: 1.0, "its expression is not a scalar UFL expression"),
    (lambda U, p: ufl.as_vector([U[0], U[0]]), r"of shape \(2,\)"),
])
def test_an_output_field_that_is_no_scalar_expression_is_one_line(expression, fragment):
    with pytest.raises(FormError, match=f"model 'declares': output field 'q': .*{fragment}"):
        run(with_outputs(sc.OutputField("q", expression=expression)))


def test_an_output_field_that_is_not_finite_stops_the_run_in_one_line_and_writes_nothing(tmp_path):
    model = with_outputs(sc.OutputField("q", expression=lambda U, p: ufl.ln(U[0] - 5.0)))  # NaN where eta < 5
    with pytest.raises(FormError, match=r"model 'declares': an output field \(q\) is not finite at a stored time"):
        run(model, output=sc.Output(tmp_path / "o", pictures=False))
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(("change", "fragment"), [
    ({"fields": "reaction"}, "fields must be a tuple of strs"),
    ({"constants": ModelConstant("k", 1.0)}, "constants must be a tuple of ModelConstants"),
    ({"outputs": sc.OutputField("q")}, "outputs must be a tuple of OutputFields"),
    ({"stored_energy": 0}, "stored_energy must be a function or None"),
    ({"constants": (ModelConstant("k", 1.0), ModelConstant("k", 2.0))}, "constants name 'k' twice"),
])
def test_a_declaration_of_the_wrong_kind_is_one_line_naming_the_model(change, fragment):
    with pytest.raises(FormError, match=f"model 'declares': {fragment}"):
        run(dataclasses.replace(sc.inelastic, name="declares", **change))


def test_a_constants_empty_open_range_is_refused():
    with pytest.raises(ValueError, match=r"a number in \(1, 1\] holds no number"):
        ModelConstant("k", low=1.0, high=1.0, low_open=True)


def test_show_keeps_the_scenes_parameters_for_a_model_named_with_model(monkeypatch):
    from stringcontact.cli.report import show_scene

    scene = sc.load_scene("example1").replace(parameters={"k": 100.0})
    shown = tomllib.loads(show_scene(scene))
    assert shown["parameters"] == {"k": 100.0} and shown["model"] == "inelastic"


def test_show_writes_a_constants_description_on_one_comment_line(monkeypatch):
    from stringcontact.cli.report import show_scene
    from stringcontact.model import registry

    model = dataclasses.replace(sc.inelastic, name="two_lines",
                                constants=(ModelConstant("k", 1.0, description="first line\nk = 'not toml"),))
    monkeypatch.setattr(registry, "load_model", lambda spec: model)
    shown = tomllib.loads(show_scene(sc.load_scene("example1")))
    assert shown["parameters"] == {"k": 1.0}


def test_an_unknown_release_is_refused_under_every_scheme():
    with pytest.raises(FormError, match="release: model 'declares' declares release 'elastic'"):
        run(dataclasses.replace(sc.inelastic, name="declares", release="elastic"), scheme="paper")


def test_the_errors_the_exit_codes_page_names_are_importable():
    from stringcontact import errors

    assert (sc.SolverError, sc.OutputError, sc.Interrupted) == (errors.SolverError, errors.OutputError,
                                                                 errors.Interrupted)
