"""PyVista accessor ``dataset.erosion.<stage>(...)``.

Registered through the ``pyvista.accessors`` entry point, so it is available
on every dataset as soon as pverosion is installed, without an import. Each
method is the public function of its stage (:mod:`pverosion.api`) with this
dataset as the input: the same keyword-only options, defaults and
``progress_bar``; the method names are the stages' names (CLI subcommands
with ``_`` for ``-``), see :data:`pverosion._stages.STAGE_INDEX`.
"""

from __future__ import annotations

import warnings

import pyvista as pv

from pverosion import api
from pverosion._frontend import accessor_method


@pv.register_dataset_accessor("erosion", pv.DataSet)
class ErosionAccessor:
    """Namespace of pverosion stages on PyVista datasets; every method returns a new dataset."""

    def __init__(self, dataset: pv.DataSet):
        self._dataset = dataset

    curvature = accessor_method(api.curvature, "Per-vertex curvature of this surface")
    weather = accessor_method(api.weather, "Curvature-driven weathering of this surface")
    hydraulic = accessor_method(api.hydraulic_erosion, "Hydraulic erosion of this closed mesh by a particle fluid")
    materials = accessor_method(api.materials_from_volume, "BSP material field built from this image volume")
    voxel = accessor_method(api.voxel_erosion, "Voxel hydraulic erosion of this voxel grid")
    shard_graph = accessor_method(api.shard_graph, "Voronoi shards of this closed mesh")
    freeze_thaw = accessor_method(api.freeze_thaw, "Freeze–thaw weathering of this closed mesh")
    repair = accessor_method(api.repair, "Self-intersections of this closed mesh removed")
    boolean = accessor_method(api.boolean, "Boolean ``operation`` of this closed mesh (A) and ``b``")

    def shards(self, **options) -> pv.MultiBlock:
        """Deprecated name of :meth:`shard_graph` (the CLI's ``shards`` was freeze-thaw); warns ``DeprecationWarning``."""
        warnings.warn("mesh.erosion.shards() is deprecated; use mesh.erosion.shard_graph()", DeprecationWarning,
                      stacklevel=2)
        return api.shard_graph(self._dataset, **options)
