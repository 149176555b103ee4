"""`Output`'s pictures (a function of one's own adds to the default pictures, or replaces them when asked) and an
output folder's refusal in the caller's terms (Python's `Output(force=True)`, the command line's --force)."""

import matplotlib.image as mpimg
import numpy as np
import pytest

import stringcontact as sc
from stringcontact.cli.main import main
from stringcontact.errors import OutputError

SMALL = {"nx": 40, "nt": 40, "eps": 0.01}  # r = 0.75


def _mine(result, folder):
    """A picture of one's own: η at the last stored time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(3, 2), dpi=50)
    ax.plot(result.x, result.eta[-1])
    fig.savefig(folder / "mine.png")
    plt.close(fig)


@pytest.mark.slow
def test_a_picture_function_adds_to_the_default_pictures(tmp_path):
    scene = sc.load_scene("example1").replace(**SMALL)
    sc.simulate(scene, output=sc.Output(tmp_path / "both", pictures=_mine))
    both = {p.name for p in (tmp_path / "both").glob("*.png")}
    assert {"mine.png", "contact_set.png", "snapshots.png", "energy.png", "space_time.png"} <= both
    assert mpimg.imread(tmp_path / "both" / "mine.png").shape[:2] == (100, 150)  # read back: the function's own
    sc.simulate(scene, output=sc.Output(tmp_path / "own", pictures=_mine, default_pictures=False))
    assert {p.name for p in (tmp_path / "own").glob("*.png")} == {"mine.png"}
    sc.simulate(scene, output=sc.Output(tmp_path / "none", pictures=False))
    assert not list((tmp_path / "none").glob("*.png"))
    with pytest.raises(ValueError, match="default_pictures: expected True or False"):
        sc.Output(tmp_path / "x", pictures=_mine, default_pictures="no")
    with pytest.raises(ValueError, match="pictures: expected True, False or a function"):
        sc.Output(tmp_path / "x", pictures="yes")


def test_a_refused_folder_says_how_to_force_in_the_callers_terms(tmp_path, capsys):
    full = tmp_path / "full"
    full.mkdir()
    (full / "notes.txt").write_text("mine")
    scene = sc.load_scene("example1").replace(**SMALL)
    with pytest.raises(OutputError) as info:
        sc.simulate(scene, output=sc.Output(full, pictures=False))
    message = str(info.value)
    assert "pass Output(..., force=True) to replace it" in message and "--force" not in message
    assert message.startswith(f"output folder {full}") and "--out" not in message
    assert (
        main(
            [
                "run",
                "example1",
                "--nx",
                "40",
                "--nt",
                "40",
                "--eps",
                "0.01",
                "--no-progress",
                "--no-pictures",
                "--out",
                str(full),
            ]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert "pass --force to replace it" in err and "Output(" not in err
    assert np.array_equal(sorted(p.name for p in full.iterdir()), ["notes.txt"])  # nothing written


def test_a_projection_scene_may_omit_eps(tmp_path):
    """Scheme projection does not read eps: a scene for it may leave it out (its summary's r is nan); a penalty
    scheme on that scene is refused in one line naming eps."""
    data = {"T": 0.1, "alpha": 0.01, "nx": 40, "nt": 100, "eta0": "0.1", "v0": -5, "h": 0.1, "scheme": "projection"}
    scene = sc.Scene.from_dict(data)
    assert scene.eps is None and "eps" not in scene.as_dict()
    from stringcontact.cli.report import show_scene

    assert "# eps: not given: scheme projection does not read it" in show_scene(scene)
    res = sc.simulate(scene, output=sc.Output(tmp_path / "run", pictures=False))
    assert res.status == "complete" and res.penalty == "none"
    assert '"r": "nan"' in (tmp_path / "run" / "summary.json").read_text()
    with pytest.raises(sc.SceneError, match="eps: scheme 'paper' needs the penalty's eps, and the scene gives none"):
        sc.simulate(scene, scheme="paper")
    with pytest.raises(sc.SceneError, match="eps: scheme 'newmark' needs the penalty's eps, and the scene gives none"):
        sc.simulate(scene.replace(scheme="newmark"))  # the scene itself loads no scheme: the run refuses it
