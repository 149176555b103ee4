"""`fenics_versions`: UFL's and FFCx's versions read without importing pkg_resources, and pkg_resources itself
still whole for anyone who imports it. Each case runs in a fresh interpreter (what is imported matters)."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
import textwrap

import pytest

HAS_PKG_RESOURCES = importlib.util.find_spec("pkg_resources") is not None


def _python(code: str) -> str:
    proc = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout.strip()


def test_ufl_and_ffcx_have_their_versions_and_the_real_pkg_resources_is_not_imported():
    out = _python("""
        import sys, types
        from importlib.metadata import version
        import stringcontact
        from stringcontact.fem import operators  # dolfinx, UFL, FFCx: as a run imports them
        import ffcx, ufl
        assert ufl.__version__ == version("fenics-ufl"), ufl.__version__
        assert ffcx.__version__ == version("fenics-ffcx"), ffcx.__version__
        loaded = sys.modules.get("pkg_resources")
        print("real" if type(loaded) is types.ModuleType else "not imported")
    """)
    assert out == "not imported"


@pytest.mark.skipif(not HAS_PKG_RESOURCES, reason="pkg_resources (setuptools) is not installed")
def test_the_stand_in_answers_find_spec_with_pkg_resources_spec():
    out = _python("""
        import importlib.util, sys
        import stringcontact
        spec = importlib.util.find_spec("pkg_resources")  # a ValueError if the module in sys.modules had no spec
        print(spec.name, type(sys.modules["pkg_resources"]).__name__)
    """)
    assert out == "pkg_resources _Versions"


@pytest.mark.skipif(not HAS_PKG_RESOURCES, reason="pkg_resources (setuptools) is not installed")
def test_pkg_resources_imported_afterwards_is_the_real_one():
    out = _python("""
        import sys, types
        from importlib.metadata import version
        import stringcontact
        import ufl
        import pkg_resources
        assert pkg_resources.get_distribution("numpy").version == version("numpy")  # not a FEniCS name: the real one
        assert type(sys.modules["pkg_resources"]) is types.ModuleType
        import pkg_resources as again
        assert again is sys.modules["pkg_resources"] and again.working_set is not None
        print(again.get_distribution("fenics-ufl").location != "")
    """)
    assert out == "True"


def test_nothing_is_stood_in_for_once_pkg_resources_is_imported():
    out = _python("""
        import sys, types
        try:
            import pkg_resources
        except ImportError:
            pkg_resources = None
        import stringcontact
        print(sys.modules.get("pkg_resources") is pkg_resources)
    """)
    assert out == "True"
