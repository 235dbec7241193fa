"""Array-only kernels: NumPy, SciPy and numba in, arrays out. No VTK, no PyVista.

The names below load their module on first use, so importing one kernel module
(``pverosion.kernels.validation``, say) does not compile or load the others.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING

_LAZY = {
    "CurvatureOperator": "curvature",
    "CurvatureResult": "curvature",
    "principal_curvatures": "curvature",
    "average_edge_length": "geometry",
    "corner_areas": "geometry",
    "face_normals": "geometry",
    "point_areas": "geometry",
    "signed_volume": "geometry",
    "vertex_normals": "geometry",
    "laplacian_vectors": "laplacian",
    "uniform_laplacian": "laplacian",
    "normalize_curvature": "normalize",
    "normalize_shifted": "normalize",
    "normalize_symmetric": "normalize",
    "Orientation": "orientation",
    "orient_faces": "orientation",
    "winding_number": "orientation",
    "EdgeTopology": "topology",
    "boundary_edges": "topology",
    "boundary_vertices": "topology",
    "edge_topology": "topology",
    "locality_order": "topology",
    "one_ring": "topology",
    "vertex_face_incidence": "topology",
    "InvalidMeshError": "validation",
    "as_faces": "validation",
    "as_points": "validation",
    "as_triangle_mesh": "validation",
}

__all__ = sorted(_LAZY)

if TYPE_CHECKING:
    from pverosion.kernels.curvature import CurvatureOperator, CurvatureResult, principal_curvatures
    from pverosion.kernels.geometry import (
        average_edge_length,
        corner_areas,
        face_normals,
        point_areas,
        signed_volume,
        vertex_normals,
    )
    from pverosion.kernels.laplacian import laplacian_vectors, uniform_laplacian
    from pverosion.kernels.normalize import normalize_curvature, normalize_shifted, normalize_symmetric
    from pverosion.kernels.orientation import Orientation, orient_faces, winding_number
    from pverosion.kernels.topology import (
        EdgeTopology,
        boundary_edges,
        boundary_vertices,
        edge_topology,
        locality_order,
        one_ring,
        vertex_face_incidence,
    )
    from pverosion.kernels.validation import InvalidMeshError, as_faces, as_points, as_triangle_mesh


def __getattr__(name: str):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'pverosion.kernels' has no attribute {name!r}")
    value = getattr(import_module(f"pverosion.kernels.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
