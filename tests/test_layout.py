"""The package's layout: kernels stay array-only, moved modules keep their old names for a release."""

from __future__ import annotations

import importlib
import pkgutil
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

import pverosion.kernels
from pverosion._moved import MOVED_MODULES
from pverosion.examples import data_path

KERNEL_MODULES = sorted(info.name for info in pkgutil.walk_packages(pverosion.kernels.__path__, "pverosion.kernels."))


def test_the_kernels_are_topic_subpackages():
    packages = {name.split(".")[2] for name in KERNEL_MODULES if name.count(".") >= 3}
    assert {"mesh", "spatial", "exact", "repair", "curvature", "solver", "weathering", "fluid", "hydraulic",
            "materials", "voxel", "shards"} <= packages
    flat = [name for name in KERNEL_MODULES if name.count(".") == 2 and not name.split(".")[2].startswith("_")]
    assert flat == [f"pverosion.kernels.{n}" for n in ("curvature", "exact", "files", "fluid", "hydraulic", "materials", "mesh",
                                                        "random_streams", "repair", "shards", "solver", "spatial",
                                                        "tolerances", "validation", "voxel", "weathering")]


def test_every_kernel_module_imports_without_vtk_pyvista_tqdm_or_matplotlib():
    blocked = ["vtk", "vtkmodules", "pyvista", "tqdm", "matplotlib", "paraview", "distributed", "dask"]
    script = (
        "import sys, importlib\n"
        f"for name in {blocked!r}:\n"
        "    sys.modules[name] = None  # any import of it raises ImportError\n"
        f"for name in {KERNEL_MODULES!r}:\n"
        "    importlib.import_module(name)\n"
        f"assert not any(sys.modules.get(n) for n in {blocked!r})\n"
        "print(len(sys.modules))\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr


def test_every_kernel_is_compiled_by_the_package_decorator():
    """pverosion.kernels._jit.njit: without numba's C-callable wrapper, which no kernel uses (compile time)."""
    from numba.core.registry import CPUDispatcher

    kernels = [(name, key, value) for name in KERNEL_MODULES
               for key, value in vars(importlib.import_module(name)).items()
               if isinstance(value, CPUDispatcher) and value.py_func.__module__ == name]
    assert len(kernels) > 300
    assert [(name, key) for name, key, value in kernels if not value.targetoptions.get("no_cfunc_wrapper")] == []


@pytest.mark.parametrize("old", sorted(MOVED_MODULES))
def test_an_old_module_path_is_the_moved_module_with_a_deprecation_warning(old):
    sys.modules.pop(old, None)
    with pytest.warns(DeprecationWarning, match=MOVED_MODULES[old].replace(".", r"\.")):
        module = importlib.import_module(old)
    assert module is importlib.import_module(MOVED_MODULES[old])


@pytest.mark.parametrize("package, module", [("pverosion.kernels.curvature", "operator"),
                                             ("pverosion.kernels.weathering", "model"),
                                             ("pverosion.kernels.materials", "field"),
                                             ("pverosion.kernels.shards", "graph"),
                                             ("pverosion.scenes", "weathering")])
def test_a_package_that_replaced_its_module_still_offers_the_module_names(package, module):
    pkg = importlib.import_module(package)
    inner = importlib.import_module(f"{package}.{module}")
    assert list(pkg.__all__) == list(inner.__all__)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert all(getattr(pkg, name) is getattr(inner, name) for name in inner.__all__)
    private = next(name for name in vars(inner) if name not in inner.__all__ and not name.startswith("__"))
    with pytest.warns(DeprecationWarning):
        assert getattr(pkg, private) is getattr(inner, private)
    with pytest.raises(AttributeError):
        pkg.no_such_name  # noqa: B018


def test_the_package_imports_no_moved_path():
    """Code, tests, pipelines and benchmarks use the new paths, so users see no warning from them."""
    out = subprocess.run(["git", "grep", "-n", "-E", "|".join(old.replace(".", r"\.") + r"\b" for old in MOVED_MODULES),
                          "--", "*.py", ":!pverosion/_moved.py", ":!tests/test_layout.py"],
                         capture_output=True, text=True, cwd=pverosion.kernels.__path__[0])
    assert out.stdout == ""


def test_data_path_is_the_environment_folder_or_the_one_beside_the_checkout(monkeypatch, tmp_path):
    monkeypatch.setenv("PVEROSION_DATA", str(tmp_path))
    assert data_path("bunny.ply") == tmp_path / "bunny.ply"
    monkeypatch.delenv("PVEROSION_DATA")
    checkout = Path(pverosion.kernels.__file__).resolve().parents[2]
    assert data_path() == checkout.parent / "shared" / "data"
    assert data_path("HeadMRVolume.mhd").parent == data_path()
