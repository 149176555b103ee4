"""The step's linear solver (docs/explanation/linear_solvers.md): LU or CG by size, PETSc options from a scene or the CLI.

CG must keep every scheme's energy ledger closed and give LU's η; a scene's options are allow-listed data
and never reach PETSc's global options database; they round-trip through TOML and the scene's dict.
"""

from __future__ import annotations

import json
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
from petsc4py import PETSc

import stringcontact as sc
from stringcontact.cli.main import main
from stringcontact.errors import SceneError, SolverError
from stringcontact.scene import Scene, limits, scene_to_toml
from stringcontact.timestepping import linear

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests/: conftest.py

CG_AMG = {"ksp_type": "cg", "pc_type": "hypre"}
#: What a run with BoomerAMG reports: hypre's, or gamg in its place where PETSc has no hypre (the dolfinx wheel's).
AMG_NAME = "hypre boomeramg" if linear.has_hypre() else "gamg"
#: The size rule's AMG options as this PETSc takes them.
AMG = linear.without_hypre(linear.AMG)[0]
CG_JACOBI = {"ksp_type": "cg", "pc_type": "jacobi"}
#: CG against LU: max |η_CG − η_LU| ≤ AGREE · max(1, max |η_LU|) (CG_RTOL = 1e-14 of the right-hand side).
AGREE = 1e-11


def contact_scene(**keys) -> Scene:
    """The square of test_membrane: thrown onto the obstacle, lands over a third of its area."""
    data = dict(domain="rectangle", cells=[12, 12], T=0.4, nt=80, alpha=0.02, scheme={"eps": 0.005},
                eta0="0.05 + 0.1*sin(pi*x)*sin(pi*y)", v0="-2*sin(pi*x)*sin(pi*y)", h=0.05)
    data.update(keys)
    return Scene.from_dict(data)


def small_drum() -> Scene:
    return sc.load_scene("drum").replace(mesh_size=0.08, T=0.4, nt=80, output_times=[0.2])


def our_options() -> list[str]:
    return [k for k in PETSc.Options().getAll() if k.startswith(linear.PREFIX)]


# --- the rule ------------------------------------------------------------------------------------------


def test_the_size_rule_picks_lu_up_to_the_limit_then_cg():
    assert linear.solver_options(linear.LU_MAX_NODES, 1) == linear.DIRECT
    mumps = dict(linear.DIRECT, pc_factor_mat_solver_type="mumps")
    assert linear.solver_options(linear.LU_MAX_NODES_PARALLEL, 2) == mumps
    assert linear.solver_options(linear.LU_MAX_NODES_PARALLEL + 1, 2)["ksp_type"] == "cg"
    assert linear.solver_options(linear.LU_MAX_NODES, 2, dim=1) == mumps  # a string: no fill, LU on any ranks
    big = linear.LU_MAX_NODES + 1
    assert linear.solver_options(big, 1) == linear.ITERATIVE | AMG  # condition unknown
    assert linear.solver_options(big, 1, condition=linear.JACOBI_MAX_CONDITION) == linear.ITERATIVE | linear.JACOBI
    assert linear.solver_options(big, 2, condition=2 * linear.JACOBI_MAX_CONDITION) == linear.ITERATIVE | AMG


@pytest.mark.parametrize("nodes", [10_000, 100_489, 1_000_000, 1001 * 1001])
def test_in_serial_every_membrane_a_scene_allows_takes_lu(nodes):
    """docs/explanation/linear_solvers.md ("Issue 28"): the serial back-substitution was the cheapest step in flight at every
    size up to the scene's cap, 1001² nodes (the cap's own mesh took CG before: 1e6 was the limit)."""
    assert nodes <= limits.MAX_MEMBRANE_NODES
    assert linear.solver_options(nodes, 1) == linear.DIRECT


@pytest.mark.parametrize("nodes", [1024, 4096, 10_000, 40_000, 100_489, 1_000_000])
def test_on_two_ranks_a_membrane_from_1e3_nodes_takes_cg_not_mumps(nodes):
    """MUMPS on 2 ranks was slower per step than CG + Jacobi at every size measured, 1024 to 1e6 nodes (it kept
    up to 4e4 before); projection's matrix there is nearly diagonal (Gershgorin bound 5 to 41): Jacobi."""
    chosen = linear.solver_options(nodes, 2, condition=41.0)
    assert chosen == linear.ITERATIVE | linear.JACOBI


def test_on_two_ranks_a_tiny_membrane_and_any_string_keep_mumps():
    mumps = dict(linear.DIRECT, pc_factor_mat_solver_type="mumps")
    assert linear.solver_options(1_000, 2) == mumps
    assert linear.solver_options(1_000_000, 2, dim=1) == mumps


def tridiagonal(diagonal: float, off: float, n: int = 50) -> PETSc.Mat:
    from mpi4py import MPI

    A = PETSc.Mat().createAIJ([n, n], nnz=3, comm=MPI.COMM_SELF)
    for i in range(n):
        A[i, i] = diagonal
        for j in (i - 1, i + 1):
            if 0 <= j < n:
                A[i, j] = off
    A.assemble()
    return A


@pytest.mark.parametrize("diagonal, off", [(1.0, 0.0), (4.0, -1.0), (2.5, -1.0), (2.0, -1.0)])
def test_the_jacobi_condition_bound_is_gershgorins_and_bounds_the_true_one(diagonal, off):
    A = tridiagonal(diagonal, off)
    rho = 2 * abs(off) / diagonal
    bound = linear.jacobi_condition_bound(A)
    assert bound == (pytest.approx((1 + rho) / (1 - rho)) if rho < 1 else np.inf)
    eig = np.linalg.eigvalsh(A.convert("dense").getDenseArray())
    assert eig.max() / eig.min() <= bound


@pytest.mark.parametrize("given, kind", [({"ksp_type": "cg"}, "cg"), ({"pc_type": "jacobi"}, "cg"),
                                         ({"pc_type": "lu"}, "preonly"), ({"ksp_type": "preonly"}, "preonly")])
def test_a_users_ksp_or_pc_type_picks_the_path_whatever_the_size(given, kind):
    for n in (10, 10 * linear.LU_MAX_NODES):
        chosen = linear.solver_options(n, 1, given)
        assert chosen["ksp_type"] == kind and all(chosen[k] == v for k, v in given.items())
        if kind == "cg":
            assert chosen["ksp_rtol"] == linear.CG_RTOL  # the ledger's tolerance stays unless the user sets one


def test_one_d_runs_pick_lu_and_give_the_same_numbers_bit_for_bit():
    scene = sc.load_scene("example1").replace(nx=200, nt=400)
    auto = sc.simulate(scene)
    forced = sc.simulate(scene, petsc_options={"ksp_type": "preonly", "pc_type": "lu"})
    assert auto.solver["linear solver"] == "LU (petsc)"
    assert np.array_equal(auto.eta, forced.eta) and np.array_equal(auto.velocity, forced.velocity)


def test_above_the_limit_cg_takes_jacobi_for_a_mass_dominated_matrix_else_amg(monkeypatch):
    monkeypatch.setattr(linear, "LU_MAX_NODES", 0)  # every mesh is "large"
    light = sc.simulate(contact_scene(), scheme="projection")  # M/Δt² + C/Δt at a stable Δt
    heavy = sc.simulate(contact_scene(cells=[24, 24], nt=1), scheme="newmark")  # Δt = 10 Δx: K dominates
    assert light.solver["linear solver"].startswith("cg + jacobi")
    assert heavy.solver["linear solver"].startswith("cg + " + AMG_NAME)
    assert np.max(np.abs(light.balance_residual)) <= 1e-10 * light.total_energy[0]
    diagonal = sc.simulate(contact_scene(alpha=0), scheme="projection")  # A = M/Δt²: the nodal maximum, no solve
    assert diagonal.solver["linear solver"].startswith("none: the step matrix is diagonal")


def test_without_hypre_boomeramg_becomes_gamg_and_the_result_says_so(monkeypatch):
    """PETSc without hypre (the dolfinx wheel's): BoomerAMG asked for, by the size rule, a model's hints (a
    fieldsplit's sub-solvers) or the user, becomes gamg, hypre's own options go, and `Result.solver` says so."""
    monkeypatch.setattr(linear, "has_hypre", lambda: False)
    asked = {"ksp_type": "cg", "pc_type": "hypre", "pc_hypre_type": "boomeramg", "fieldsplit_1_pc_type": "hypre",
             "ksp_rtol": 1e-12}
    kept, note = linear.without_hypre(asked)
    assert kept == {"ksp_type": "cg", "pc_type": "gamg", "fieldsplit_1_pc_type": "gamg", "ksp_rtol": 1e-12}
    assert note is not None and "gamg" in note and "hypre" in note
    assert linear.without_hypre(CG_JACOBI) == (CG_JACOBI, None)
    linear.check_option_values(asked)  # accepted: it will run
    res = sc.simulate(contact_scene(nt=8, T=0.04), scheme="newmark", petsc_options=CG_AMG)
    assert res.solver["linear solver"].startswith("cg + gamg") and "in place of hypre" in res.solver["linear solver"]
    assert res.status == "complete"


def test_the_mean_iterations_count_the_contact_steps_free_solves_too():
    """projection's contact step solves the free step with its own solver first; a membrane in flight makes
    only those solves, and the summary's mean must count them (it said "mean 0.0 iterations")."""
    flying = contact_scene(v0="0", T=0.02, nt=4)  # 4 steps, nowhere near the obstacle
    res = sc.simulate(flying, scheme="projection", petsc_options=CG_JACOBI)
    assert res.contact_measure.max() == 0.0
    mean = float(res.solver["linear solver"].split("mean ")[1].split()[0])
    assert mean >= 1.0


# --- accuracy with CG -----------------------------------------------------------------------------------


@pytest.mark.parametrize("options", [CG_AMG, CG_JACOBI], ids=["amg", "jacobi"])
@pytest.mark.parametrize("scheme", sc.SCHEMES)
def test_cg_keeps_the_ledger_closed_and_agrees_with_lu(scheme, options):
    lu = sc.simulate(contact_scene(), scheme=scheme)
    cg = sc.simulate(contact_scene(), scheme=scheme, petsc_options=options)
    assert lu.solver["linear solver"].startswith("LU")
    assert cg.solver["linear solver"].startswith("cg + " + (AMG_NAME if options is CG_AMG else "jacobi"))
    assert cg.status == "complete"  # the energy guard (no rise above 1e-9 E(0) per step) never fired
    assert cg.contact_measure.max() > 0.1
    assert np.max(np.abs(cg.balance_residual)) <= 1e-10 * cg.total_energy[0]
    assert np.max(np.abs(cg.eta - lu.eta)) <= AGREE * max(1.0, np.max(np.abs(lu.eta)))


@pytest.mark.slow
@pytest.mark.parametrize("scheme, penalty", [("projection", None), ("newmark", None), ("paper", "semi-implicit")])
def test_the_drum_lands_alike_with_cg(scheme, penalty):
    lu = sc.simulate(small_drum(), scheme=scheme, penalty=penalty)
    cg = sc.simulate(small_drum(), scheme=scheme, penalty=penalty, petsc_options=CG_AMG)
    assert cg.status == "complete" and cg.contact_measure.max() > 0
    assert np.max(np.abs(cg.balance_residual)) <= 1e-10 * cg.total_energy[0]
    assert np.max(np.abs(cg.eta - lu.eta)) <= AGREE * max(1.0, np.max(np.abs(lu.eta)))
    assert np.array_equal(cg.contact, lu.contact)


@pytest.mark.parametrize("scheme, penalty", [("newmark", None), ("paper", "semi-implicit")])
def test_a_changed_damping_sets_cg_up_again_and_is_counted(scheme, penalty):
    lu = sc.simulate(contact_scene(), scheme=scheme, penalty=penalty)
    cg = sc.simulate(contact_scene(), scheme=scheme, penalty=penalty, petsc_options=CG_AMG)
    assert cg.counters["refactorisations"] == lu.counters["refactorisations"] > 0


def test_a_loose_tolerance_shows_in_the_ledger():
    """The ledger is the check on the tolerance: CG stopped early leaves a visible residual."""
    loose = sc.simulate(contact_scene(), scheme="paper", petsc_options=dict(CG_JACOBI, ksp_rtol=1e-6))
    assert np.max(np.abs(loose.balance_residual)) > 1e-10 * loose.total_energy[0]


def test_a_solver_that_does_not_converge_stops_the_run_in_one_line():
    with pytest.raises(SolverError, match="did not converge"):
        sc.simulate(contact_scene(), scheme="paper", petsc_options=dict(CG_JACOBI, ksp_max_it=1))


def test_a_solver_that_does_not_converge_is_an_internal_failure_not_bad_input(capsys):
    """docs/explanation/reliability.md: exit 2 is bad input; a CG that stops short after the input was accepted is exit 1."""
    from stringcontact.cli.main import EXIT_INTERNAL, main

    code = main(["run", "example1", "--nx", "50", "--nt", "1000", "--no-pictures", "--no-progress",
                 "--petsc-option", "ksp_type=cg", "--petsc-option", "pc_type=jacobi", "--petsc-option", "ksp_max_it=1"])
    err = capsys.readouterr().err
    assert code == EXIT_INTERNAL == 1
    assert "did not converge" in err and len(err.strip().splitlines()) == 1


# --- options: private, allow-listed, round-tripped -------------------------------------------------------


def test_options_stay_with_their_simulation():
    PETSc.Options().setValue("ksp_type", "gmres")  # someone else's global option: not ours (own prefix)
    try:
        cg = sc.simulate(contact_scene(nt=8, T=0.04), scheme="projection", petsc_options=CG_JACOBI)
        assert our_options() == []
        after = sc.simulate(contact_scene(nt=8, T=0.04), scheme="projection")
    finally:
        PETSc.Options().delValue("ksp_type")
    assert cg.solver["linear solver"].startswith("cg + jacobi")
    assert after.solver["linear solver"] == "LU (petsc)"


def test_the_argument_overrides_the_scene_option_by_option():
    scene = contact_scene(nt=8, T=0.04, petsc_options={"ksp_type": "cg", "pc_type": "hypre"})
    assert sc.simulate(scene).solver["linear solver"].startswith("cg + " + AMG_NAME)
    assert sc.simulate(scene, petsc_options={"pc_type": "jacobi"}).solver["linear solver"].startswith("cg + jacobi")


@pytest.mark.parametrize("bad", [
    {"options_file": "x"}, {"ksp_view": True}, {"ksp_monitor": True}, {"log_view": True},
    {"on_error_attach_debugger": True}, {"start_in_debugger": True}, {"ksp_converged_reason": True},
    {"pc_hypre_boomeramg_print_statistics": 1}, {"mat_mumps_icntl_1": 6}, {"mat_mumps_icntl_22": 1},
    {"ksp_type": "python"}, {"ksp_type": "a/b"}, {"ksp_type": "ascii:out.txt"}, {"ksp_rtol": float("inf")},
    {"ksp_type": ["cg"]}, {"-ksp_type": "cg"}, {"snes_type": "newtonls"}, {"KSP_TYPE": "cg"}, "ksp_type=cg",
    {f"ksp_rtol{'_' * i}": 1 for i in range(40)},
])
def test_bad_options_are_refused_in_one_line_naming_the_key(bad):
    with pytest.raises(SceneError) as info:
        contact_scene(petsc_options=bad)
    message = str(info.value)
    assert "petsc_options" in message and "allowed" in message and "\n" not in message


def test_a_name_in_capitals_is_refused_with_its_lower_case_spelling(capsys):
    """PETSc's manual writes pc_hypre_boomeramg_P_max; its names are case-insensitive, the table's are lower case."""
    with pytest.raises(SceneError) as info:
        contact_scene(petsc_options={"pc_type": "hypre", "pc_hypre_boomeramg_P_max": 4})
    assert "'pc_hypre_boomeramg_p_max'" in str(info.value) and "lower case" in str(info.value)
    assert dict(contact_scene(petsc_options={"pc_hypre_boomeramg_p_max": 4}).petsc_options) == {
        "pc_hypre_boomeramg_p_max": 4}
    assert main(["run", "example1", "--nx", "20", "--nt", "20", "--petsc-option", "KSP_VIEW=1"]) == 2
    err = capsys.readouterr().err  # a refused word stays refused in any case, without the hint
    assert err.count("\n") == 1 and "KSP_VIEW" in err and "write it in lower case" not in err


def test_options_round_trip_through_toml_and_the_dict():
    options = {"ksp_type": "cg", "pc_type": "hypre", "pc_hypre_type": "boomeramg", "ksp_rtol": 1e-12,
               "ksp_max_it": 500, "ksp_initial_guess_nonzero": True, "pc_hypre_boomeramg_coarsen_type": "HMIS"}
    scene = contact_scene(petsc_options=options)
    assert scene.as_dict()["petsc_options"] == options
    assert Scene.from_dict(scene.as_dict()) == scene
    assert Scene.from_dict(tomllib.loads(scene_to_toml(scene))) == scene
    assert "petsc_options" not in contact_scene().as_dict()  # nothing given, nothing written


def test_cli_options_win_over_the_scene_and_are_recorded(tmp_path, capsys):
    path = tmp_path / "square.toml"
    path.write_text(scene_to_toml(contact_scene(nt=8, T=0.04, petsc_options=CG_AMG)))
    assert main(["show", str(path)]) == 0
    assert tomllib.loads(capsys.readouterr().out)["petsc_options"] == {"ksp_type": "cg", "pc_type": "hypre"}
    out = tmp_path / "out"
    code = main(["run", str(path), "--no-progress", "--no-pictures", "--out", str(out),
                 "--petsc-option", "pc_type=jacobi", "--petsc-option", "ksp_rtol=1e-13"])
    assert code == 0
    assert "linear solver: cg + jacobi, mean" in capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    stored = Scene.from_dict(summary["scene"])
    assert dict(stored.petsc_options) == {"ksp_type": "cg", "pc_type": "jacobi", "ksp_rtol": 1e-13}


@pytest.mark.parametrize("item", ["options_file=/etc/passwd", "ksp_view", "ksp_type=a:b", "ksp_monitor=true"])
def test_cli_refuses_bad_options_with_exit_2(tmp_path, capsys, item):
    assert main(["run", "example1", "--nx", "20", "--nt", "20", "--petsc-option", item]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "petsc_options" in err and "Traceback" not in err


# --- MPI ---------------------------------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.mpi
def test_cg_on_two_ranks_gives_the_serial_lu_answer(tmp_path):
    from conftest import mpirun

    proc = mpirun([sys.executable, Path(__file__).resolve(), tmp_path], ranks=2, timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    got = np.load(tmp_path / "cg.npz")
    for scheme in sc.SCHEMES:
        lu = sc.simulate(contact_scene(), scheme=scheme)
        assert str(got[f"{scheme}_solver"]).startswith("cg + " + AMG_NAME)
        assert np.max(np.abs(got[f"{scheme}_eta"] - lu.eta)) <= AGREE * max(1.0, np.max(np.abs(lu.eta)))
        assert float(got[f"{scheme}_balance"]) <= 1e-10 * lu.total_energy[0]


def _worker(out: Path) -> None:
    from mpi4py import MPI

    arrays = {}
    for scheme in sc.SCHEMES:
        res = sc.simulate(contact_scene(), scheme=scheme, petsc_options=CG_AMG)
        if not res.has_rows:  # the rows are on rank 0, which saves them
            continue
        arrays |= {f"{scheme}_eta": res.eta, f"{scheme}_solver": res.solver["linear solver"],
                   f"{scheme}_balance": np.max(np.abs(res.balance_residual))}
    if MPI.COMM_WORLD.rank == 0:
        np.savez(out / "cg.npz", **arrays)


if __name__ == "__main__":
    _worker(Path(sys.argv[1]))


@pytest.mark.parametrize("ordering", [2, 6])
def test_options_read_at_set_up_reach_the_solver(ordering):
    """MUMPS reads its ICNTL when it factorises, inside KSP.setUp: the options must still be in PETSc's database
    there (`linear.options_held`), or the solver silently keeps its default ordering (ICNTL(7) = 7)."""
    from mpi4py import MPI

    A = PETSc.Mat().createAIJ([6, 6], nnz=1, comm=MPI.COMM_SELF)
    for i in range(6):
        A.setValue(i, i, 2.0)
    A.assemble()
    options = {"ksp_type": "preonly", "pc_type": "lu", "pc_factor_mat_solver_type": "mumps", "mat_mumps_icntl_7": ordering}
    ksp = linear.configured_ksp(A, MPI.COMM_SELF, options)
    assert ksp.getPC().getFactorMatrix().getMumpsIcntl(7) == ordering
    assert not PETSc.Options().hasName(linear.PREFIX + "mat_mumps_icntl_7")  # nothing left for another solver
