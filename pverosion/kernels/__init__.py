"""Array-only kernels: NumPy, SciPy and numba in, arrays out. No VTK, no PyVista."""

from pverosion.kernels.curvature import (
    CurvatureOperator,
    CurvatureResult,
    principal_curvatures,
)
from pverosion.kernels.geometry import (
    average_edge_length,
    corner_areas,
    face_normals,
    point_areas,
    signed_volume,
    vertex_normals,
)
from pverosion.kernels.laplacian import laplacian_vectors, uniform_laplacian
from pverosion.kernels.normalize import (
    normalize_curvature,
    normalize_shifted,
    normalize_symmetric,
)
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
from pverosion.kernels.validation import (
    InvalidMeshError,
    as_faces,
    as_points,
    as_triangle_mesh,
)

__all__ = [
    "CurvatureOperator",
    "CurvatureResult",
    "EdgeTopology",
    "InvalidMeshError",
    "Orientation",
    "as_faces",
    "as_points",
    "as_triangle_mesh",
    "average_edge_length",
    "boundary_edges",
    "boundary_vertices",
    "corner_areas",
    "edge_topology",
    "face_normals",
    "laplacian_vectors",
    "locality_order",
    "normalize_curvature",
    "normalize_shifted",
    "normalize_symmetric",
    "one_ring",
    "orient_faces",
    "point_areas",
    "principal_curvatures",
    "signed_volume",
    "uniform_laplacian",
    "vertex_face_incidence",
    "vertex_normals",
    "winding_number",
]
