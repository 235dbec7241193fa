"""Shared plumbing of the Python front ends: run one filter class on one dataset."""

from __future__ import annotations

from typing import Any

import pyvista as pv
from vtkmodules.vtkCommonDataModel import vtkImageData, vtkPolyData

from pverosion.filters.base import ErosionFilter
from pverosion.kernels.validation import InvalidMeshError


def apply_filter(filter_cls: type[ErosionFilter], mesh, **options: Any) -> pv.DataSet:
    """Run ``filter_cls`` with ``options`` on ``mesh`` and return a new PyVista dataset.

    Raises
    ------
    TypeError
        If ``mesh`` is not the data type the filter takes, or an option is unknown.
    InvalidMeshError
        If the mesh cannot be processed.
    """
    if filter_cls.INPUT_TYPE == "vtkPolyData" and not isinstance(mesh, vtkPolyData):
        hint = " (call .extract_surface() first)" if isinstance(mesh, pv.DataSet) else ""
        raise TypeError(f"{filter_cls.__name__} needs a PolyData surface{hint}; got {type(mesh).__name__}")
    if filter_cls.INPUT_TYPE == "vtkImageData" and not isinstance(mesh, vtkImageData):
        raise TypeError(f"{filter_cls.__name__} needs an ImageData volume; got {type(mesh).__name__}")
    if isinstance(mesh, vtkPolyData) and mesh.GetNumberOfPoints() == 0:
        raise InvalidMeshError("mesh is empty: it has no points")
    return pv.wrap(filter_cls(**options).run(mesh))
