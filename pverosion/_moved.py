"""Old import paths of modules that moved, kept working for one release with a DeprecationWarning.

``import pverosion.kernels.topology`` (the flat layout) returns the module now at
``pverosion.kernels.mesh.topology``: the same module object, so attributes read
or patched through either name are the same.  The finder sits last on
:data:`sys.meta_path`, so it is asked only about names no real module has.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import warnings

__all__ = ["MOVED_MODULES", "install"]

_KERNELS = {
    "topology": "mesh.topology",
    "orientation": "mesh.orientation",
    "geometry": "mesh.geometry",
    "remesh": "mesh.remesh",
    "degenerate": "mesh.degenerate",
    "laplacian": "mesh.laplacian",
    "terrain": "mesh.terrain",
    "mesh_query": "spatial.mesh_query",
    "predicates": "exact.predicates",
    "intersection": "exact.intersection",
    "intersection_curves": "exact.intersection_curves",
    "polygon_cut": "exact.polygon_cut",
    "mesh_repair": "repair.mesh_repair",
    "normalize": "curvature.normalize",
    "mesh_evolution": "solver.mesh_evolution",
    "particle_fluid": "fluid.particle_fluid",
    "hydraulic_erosion": "hydraulic.erosion",
    "overhangs": "hydraulic.overhangs",
    "surfaces": "materials.surfaces",
    "bsp": "materials.bsp",
    "voxel_fluid": "voxel.fluid",
    "pressure": "voxel.pressure",
    "voxel_erosion": "voxel.erosion",
    "voxelize": "voxel.voxelize",
    "voronoi": "shards.voronoi",
    "seed_patterns": "shards.seed_patterns",
    "shard_geometry": "shards.geometry",
    "freeze_thaw": "shards.freeze_thaw",
}
_TOP = {
    "hydraulic_scenes": "scenes.hydraulic",
    "intersection_scenes": "scenes.intersection",
    "shard_scenes": "scenes.shards",
    "voxel_scenes": "scenes.voxel",
}

MOVED_MODULES: dict[str, str] = {
    **{f"pverosion.kernels.{old}": f"pverosion.kernels.{new}" for old, new in _KERNELS.items()},
    **{f"pverosion.{old}": f"pverosion.{new}" for old, new in _TOP.items()},
}
"""Old module name -> new module name.  ``pverosion.kernels.curvature``, ``.weathering``,
``.materials``, ``.shards`` and ``pverosion.scenes`` became packages of the same name that
re-export what the old module did, so they are not listed."""


class _Alias(importlib.abc.Loader):
    """Loads an old name as the module at its new name."""

    def __init__(self, target: str) -> None:
        self.target = target

    def create_module(self, spec):
        return None

    def exec_module(self, module) -> None:
        warnings.warn(f"{module.__name__} moved to {self.target}; the old name goes in the next release",
                      DeprecationWarning, stacklevel=2)
        sys.modules[module.__name__] = importlib.import_module(self.target)


class _MovedFinder(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname, path=None, target=None):
        new = MOVED_MODULES.get(fullname)
        return None if new is None else importlib.util.spec_from_loader(fullname, _Alias(new))


def install() -> None:
    """Put the finder of moved modules last on :data:`sys.meta_path` (once)."""
    if not any(isinstance(f, _MovedFinder) for f in sys.meta_path):
        sys.meta_path.append(_MovedFinder())


def reexport(package: str, module: str, *, lazy_names: tuple[str, ...] | None = None) -> tuple[list[str], object]:
    """``__all__`` and a module ``__getattr__`` for a package that replaced the module of its name.

    The package re-exports ``module``'s public names; other attributes the old module had
    (private helpers) are still found, with a DeprecationWarning. With ``lazy_names`` (``module``'s
    ``__all__``), ``module`` is imported on the first attribute read instead of now, so importing a
    sibling module of the package does not import it.
    """
    public = list(importlib.import_module(module).__all__ if lazy_names is None else lazy_names)

    def __getattr__(name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        try:
            value = getattr(importlib.import_module(module), name)
        except AttributeError:
            raise AttributeError(f"module {package!r} has no attribute {name!r}") from None
        if name not in public:
            warnings.warn(f"{package}.{name} is now {module}.{name}", DeprecationWarning, stacklevel=2)
        return value

    return public, __getattr__
