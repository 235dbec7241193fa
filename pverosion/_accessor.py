"""PyVista accessor ``dataset.erosion.<stage>(...)``.

Registered through the ``pyvista.accessors`` entry point, so it is available
on every dataset as soon as pverosion is installed, without an import.
"""

from __future__ import annotations

import pyvista as pv

from pverosion import api
from pverosion.kernels.repair.mesh_repair import DEFAULT_TOLERANCE


@pv.register_dataset_accessor("erosion", pv.DataSet)
class ErosionAccessor:
    """Namespace of pverosion stages on PyVista datasets; every method returns a new dataset."""

    def __init__(self, dataset: pv.DataSet):
        self._dataset = dataset

    def curvature(self, *, orientation: str = "outward", normalization: str = "none") -> pv.PolyData:
        """Per-vertex curvature; see :func:`pverosion.curvature`."""
        return api.curvature(self._dataset, orientation=orientation, normalization=normalization)

    def weather(self, **options) -> pv.PolyData:
        """Curvature-driven weathering; see :func:`pverosion.weather` for the options."""
        return api.weather(self._dataset, **options)

    def materials(self, thresholds, **options):
        """BSP material field built from this image volume; see :func:`pverosion.materials_from_volume`."""
        return api.materials_from_volume(self._dataset, thresholds, **options)

    def voxel(self, **options) -> pv.MultiBlock:
        """Voxel hydraulic erosion of this voxel grid; see :func:`pverosion.voxel_erosion`."""
        return api.voxel_erosion(self._dataset, **options)

    def shards(self, **options) -> pv.MultiBlock:
        """Voronoi shards of this closed mesh; see :func:`pverosion.shard_graph`."""
        return api.shard_graph(self._dataset, **options)

    def freeze_thaw(self, **options) -> pv.MultiBlock:
        """Freeze–thaw weathering of this closed mesh; see :func:`pverosion.freeze_thaw`."""
        return api.freeze_thaw(self._dataset, **options)

    def hydraulic(self, **options) -> pv.MultiBlock:
        """Hydraulic erosion of this closed mesh by a particle fluid; see :func:`pverosion.hydraulic_erosion`."""
        return api.hydraulic_erosion(self._dataset, **options)

    def repair(self, *, orientation: str = "outward", tolerance: float = DEFAULT_TOLERANCE,
               improve: bool = False) -> pv.PolyData:
        """Self-intersections of this closed mesh removed; see :func:`pverosion.repair`."""
        return api.repair(self._dataset, orientation=orientation, tolerance=tolerance, improve=improve)

    def boolean(self, other: pv.PolyData, operation: str = "union", *, orientation: str = "outward",
                tolerance: float = DEFAULT_TOLERANCE, improve: bool = False) -> pv.PolyData:
        """Boolean ``operation`` of this closed mesh (A) and ``other`` (B); see :func:`pverosion.boolean`."""
        return api.boolean(self._dataset, other, operation, orientation=orientation, tolerance=tolerance,
                           improve=improve)
