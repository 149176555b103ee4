"""`check` with a restitution e > 0: (A4) and the pointwise (A3) are the paper's e = 0 and say so; the landing
impulse is (1 + e) V."""

from stringcontact.analysis import theorems as th
from stringcontact.cli import main as cli


def test_a4_is_expected_only_at_e0():
    scene = th.flat_landing_scene(200, 240).replace(restitution=0.5)
    results = th.refine(scene, levels=2, penalty=None, scheme="projection")
    a4 = th.check_velocity_after_contact(results)
    assert a4.verdict == th.NOT_APPLICABLE and "expected only at e = 0" in a4.expectation and a4.measured > 0.3
    a3 = th.check_upward(results)[1]
    assert a3.verdict == th.NOT_APPLICABLE and "e = 0.5" in a3.expectation
    landing = th.check_landing(results, V=1.0)
    assert landing.verdict == th.HOLDS and "(1 + e) V = 1.5" in landing.expectation
    inelastic = th.refine(scene.replace(restitution=None), levels=2, penalty=None, scheme="projection")
    a4 = th.check_velocity_after_contact(inelastic)
    assert a4.verdict != th.NOT_APPLICABLE and a4.expectation.startswith("-> 0 under refinement")
    assert th.check_landing(inelastic, V=1.0).verdict == th.HOLDS


def test_check_reports_e(capsys):
    code = cli.main(["check", "flat-landing", "--scheme", "projection", "--restitution", "0.25", "--nx", "100",
                     "--nt", "120", "--levels", "1"])
    out = capsys.readouterr().out
    assert code == 0 and "restitution e = 0.25" in out and "expected only at e = 0" in out
