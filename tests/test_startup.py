"""Start-up cost: ``import flexmbd`` and ``flexmbd --help`` load none of the heavy libraries
(their import took most of the 0.6 s a script paid before doing anything), and the lazy
public names (PEP 562) are what they were when the package imported everything eagerly.

The checks read ``sys.modules`` in a fresh interpreter: no timing, so they cannot flake on a
loaded machine (the times are printed by ``benchmarks/startup.py``)."""

from __future__ import annotations

import inspect
import json
import os
import subprocess
import sys
import types
from pathlib import Path

import pytest

import flexmbd as fm

#: Imported only by the features that use them (a mesh file, a results file, a plot, ...).
HEAVY = ("scipy", "matplotlib", "h5py", "pydantic", "meshio", "pandas", "xarray", "dask")

#: The public names that are modules, functions and values; every other name is a class.
MODULES = {"errors", "examples"}
FUNCTIONS = {
    "axial_pulse",
    "campbell",
    "dispersion",
    "equilibrium",
    "euler_parameters_to_matrix",
    "floquet",
    "inverse_dynamics",
    "linearize",
    "linearize_at_rest",
    "load_study",
    "plot_campbell",
    "read_results",
    "rotation",
    "simulate",
    "view",
    "steady_rotation",
}
VALUES = {"__version__": str}


def _python(code: str) -> str:
    """Runs `code` in a fresh interpreter that imports this checkout's flexmbd; its stdout."""
    package = str(Path(fm.__file__).resolve().parents[1])
    path = os.environ.get("PYTHONPATH")
    env = {**os.environ, "PYTHONPATH": package + (os.pathsep + path if path else "")}
    run = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120
    )
    assert run.returncode == 0, run.stderr
    return run.stdout


def _heavy_after(code: str) -> list[str]:
    report = f"import json, sys; print(json.dumps([m for m in {HEAVY!r} if m in sys.modules]))"
    return json.loads(_python(code + "\n" + report).splitlines()[-1])


def test_import_flexmbd_loads_no_heavy_library():
    assert _heavy_after("import flexmbd") == []


@pytest.mark.parametrize("argv", [["--help"], ["run", "--help"], ["--version"]])
def test_the_command_line_help_loads_no_heavy_library(argv):
    code = (
        "import contextlib, io\n"
        "from flexmbd.cli import main\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    try:\n"
        f"        main({argv!r})\n"
        "    except SystemExit:\n"
        "        pass"
    )
    assert _heavy_after(code) == []


def test_a_rigid_simulation_loads_no_file_or_mesh_library():
    # The system and the solver need numpy only: no mesh reader, no HDF5, no plotting.
    code = (
        "import flexmbd as fm\n"
        "system = fm.System(gravity=(0, -9.81, 0))\n"
        "mass = system.add_point_mass(1.0, position=(1, 0, 0))\n"
        "system.add_distance_joint(system.add_marker(system.ground), system.add_marker(mass), 1)\n"
        "fm.simulate(system, end_time=0.01, step_size=1e-3)"
    )
    assert _heavy_after(code) == []


def test_submodules_are_attributes_on_first_access():
    # As when the package imported them all: `fm.fe.build_body` after `import flexmbd`.
    code = (
        "import flexmbd as fm\n"
        "assert fm.fe.FlexibleBodyData is fm.fe.body.FlexibleBodyData\n"
        "assert fm.animation.write_vtu_series and fm.study.Study is fm.Study\n"
        "for name in ('__main__', 'no_such_module'):\n"
        "    try:\n"
        "        getattr(fm, name)\n"
        "    except AttributeError:\n"
        "        pass\n"
        "    else:\n"
        "        raise AssertionError(name)\n"
        "print('ok')"
    )
    assert _python(code).strip() == "ok"


def _kind(value: object) -> str:
    if isinstance(value, types.ModuleType):
        return "module"
    if isinstance(value, type):
        return "class"
    if isinstance(value, types.FunctionType):
        return "function"
    return type(value).__name__


def _expected_kind(name: str) -> str:
    if name in MODULES:
        return "module"
    if name in FUNCTIONS:
        return "function"
    if name in VALUES:
        return VALUES[name].__name__
    return "class"


@pytest.mark.parametrize("order", ["names-first", "submodules-first"])
def test_every_public_name_keeps_its_kind_after_every_submodule_is_imported(order):
    # `flexmbd.campbell` is both a submodule and the function `fm.campbell`: importing the
    # submodule (the import system then sets it as the package's attribute) must not replace
    # the function, whether the name was looked up before or not.
    code = f"""
import importlib, json, pkgutil, types
import flexmbd as fm

{inspect.getsource(_kind)}
def import_all():
    for info in pkgutil.walk_packages(fm.__path__, "flexmbd."):
        if not info.name.endswith("__main__"):
            importlib.import_module(info.name)

if {order == "submodules-first"}:
    import_all()
before = {{name: getattr(fm, name) for name in fm.__all__}}
import_all()
import flexmbd.campbell, flexmbd.rotation, flexmbd.dispersion, flexmbd.inverse_dynamics
from flexmbd.campbell import campbell
star = {{}}
exec("from flexmbd import *", star)
same = [name for name in fm.__all__ if getattr(fm, name) is before[name]]
print(json.dumps({{"kinds": {{name: _kind(getattr(fm, name)) for name in fm.__all__}},
                  "same": same, "star": sorted(n for n in fm.__all__ if n in star)}}))
"""
    report = json.loads(_python(code).splitlines()[-1])
    assert report["kinds"] == {name: _expected_kind(name) for name in fm.__all__}
    assert report["same"] == list(fm.__all__)
    assert report["star"] == sorted(fm.__all__)


def test_public_names_in_this_process():
    # The test process imported many submodules already (conftest, other tests).
    for name in fm.__all__:
        assert _kind(getattr(fm, name)) == _expected_kind(name), name
    assert fm.campbell is sys.modules["flexmbd.campbell"].campbell
    assert fm.rotation("z", 0.0).shape == (3, 3)
    assert set(fm.__all__) <= set(dir(fm))
    with pytest.raises(AttributeError, match="no_such_name"):
        fm.no_such_name  # noqa: B018
