"""What `main()` does only as the process's own command (the console script, `argv` None): Open MPI's
settings for a singleton (`cli.process.quick_singleton`), what is set, when, and that Open MPI then starts no daemon; and the
objects left out of the exit's last garbage collection (`gc.freeze`)."""

from __future__ import annotations

import gc
import os
import subprocess
import sys
import textwrap

import pytest

from stringcontact.cli.process import LAUNCHED, SINGLETON, quick_singleton


def test_settings_for_a_singleton_only():
    assert quick_singleton({}) == SINGLETON
    for name in LAUNCHED:  # under mpirun the transport stays the user's and Open MPI's choice
        launched = {name: "0"}
        assert quick_singleton(launched) == {} and launched == {name: "0"}
    mine = {"OMPI_MCA_pml": "ucx"}
    assert quick_singleton(mine) == {"OMPI_MCA_ess_singleton_isolated": "1"}
    assert mine == {"OMPI_MCA_pml": "ucx", "OMPI_MCA_ess_singleton_isolated": "1"}  # the user's value kept


def _clean_env(**extra) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in SINGLETON and k not in LAUNCHED}
    return {**env, **extra}


COMMAND = textwrap.dedent(
    """
    import gc, os, sys
    from stringcontact.cli.main import main
    sys.argv = ["stringcontact", "list"]
    main()
    print("SET", os.environ.get("OMPI_MCA_pml"), os.environ.get("OMPI_MCA_ess_singleton_isolated"))
    print("FROZEN", gc.get_freeze_count() > 0)
    """
)


def _seen(env, what="SET") -> str:
    out = subprocess.run([sys.executable, "-c", COMMAND], env=env, capture_output=True, text=True, check=True).stdout
    return [line for line in out.splitlines() if line.startswith(what)][0]


def test_the_command_sets_them_before_mpi_starts():
    assert _seen(_clean_env()) == "SET ob1 1"
    assert _seen(_clean_env(OMPI_COMM_WORLD_SIZE="2")) == "SET None None"


def test_the_command_leaves_its_objects_out_of_the_last_collection():
    assert _seen(_clean_env(), "FROZEN") == "FROZEN True"


def test_called_from_python_main_changes_no_environment(monkeypatch, capsys):
    from stringcontact.cli.main import main

    for name in SINGLETON:
        monkeypatch.delenv(name, raising=False)
    assert main(["list"]) == 0
    assert not any(name in os.environ for name in SINGLETON)  # a test or notebook keeps its environment
    assert gc.get_freeze_count() == 0  # and its garbage collection


CHILDREN = textwrap.dedent(
    """
    import os
    from mpi4py import MPI
    me = str(os.getpid())
    children = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            with open(f"/proc/{pid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if fields[1] == me:
            children.append(open(f"/proc/{pid}/comm").read().strip())
    print(MPI.COMM_WORLD.size, ",".join(sorted(children)) or "-")
    """
)


@pytest.mark.skipif(not os.path.isdir("/proc"), reason="reads /proc for the process's children")
def test_open_mpi_starts_no_daemon_with_them():
    env = _clean_env(**SINGLETON)
    out = subprocess.run([sys.executable, "-c", CHILDREN], env=env, capture_output=True, text=True, check=True)
    size, children = out.stdout.split()
    assert size == "1"
    assert children == "-", f"MPI_Init started {children} for a singleton"
