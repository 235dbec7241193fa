"""Array-only kernels: NumPy, SciPy and numba in, arrays out. No VTK, no PyVista.

The names below load their module on first use, so importing one kernel module
(``pverosion.kernels.validation``, say) does not compile or load the others.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING

from pverosion.kernels import _cache_stamp

_cache_stamp.install()  # before any kernel is defined: a change to any kernel source recompiles them all

_LAZY = {
    "CurvatureOperator": "curvature.operator",
    "CurvatureResult": "curvature.operator",
    "principal_curvatures": "curvature.operator",
    "average_edge_length": "mesh.geometry",
    "corner_areas": "mesh.geometry",
    "face_normals": "mesh.geometry",
    "point_areas": "mesh.geometry",
    "signed_volume": "mesh.geometry",
    "vertex_normals": "mesh.geometry",
    "laplacian_vectors": "mesh.laplacian",
    "uniform_laplacian": "mesh.laplacian",
    "normalize_curvature": "curvature.normalize",
    "normalize_shifted": "curvature.normalize",
    "normalize_symmetric": "curvature.normalize",
    "Orientation": "mesh.orientation",
    "orient_faces": "mesh.orientation",
    "winding_number": "mesh.orientation",
    "EdgeTopology": "mesh.topology",
    "boundary_edges": "mesh.topology",
    "boundary_vertices": "mesh.topology",
    "edge_topology": "mesh.topology",
    "locality_order": "mesh.topology",
    "one_ring": "mesh.topology",
    "vertex_face_incidence": "mesh.topology",
    "InvalidMeshError": "validation",
    "as_faces": "validation",
    "as_points": "validation",
    "as_triangle_mesh": "validation",
}

__all__ = sorted(_LAZY)

if TYPE_CHECKING:
    from pverosion.kernels.curvature.normalize import normalize_curvature, normalize_shifted, normalize_symmetric
    from pverosion.kernels.curvature.operator import CurvatureOperator, CurvatureResult, principal_curvatures
    from pverosion.kernels.mesh.geometry import (
        average_edge_length,
        corner_areas,
        face_normals,
        point_areas,
        signed_volume,
        vertex_normals,
    )
    from pverosion.kernels.mesh.laplacian import laplacian_vectors, uniform_laplacian
    from pverosion.kernels.mesh.orientation import Orientation, orient_faces, winding_number
    from pverosion.kernels.mesh.topology import (
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
