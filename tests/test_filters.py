import numpy as np
import pytest
import pyvista as pv
from conftest import assert_pipeline_keeps_the_error
from vtkmodules.vtkFiltersCore import vtkTriangleFilter
from vtkmodules.vtkFiltersSources import vtkSphereSource

import pverosion
from pverosion.filters import ALL_FILTERS, Curvature
from pverosion.kernels import InvalidMeshError


def test_filter_composes_in_a_vtk_pipeline():
    source = vtkSphereSource()
    source.SetRadius(2.0)
    source.SetThetaResolution(64)
    source.SetPhiResolution(64)
    alg = Curvature(normalization="shifted")
    alg.SetInputConnection(source.GetOutputPort())
    alg.Update()
    out = pv.wrap(alg.GetOutputDataObject(0))
    H = out["mean_curvature"]
    assert np.median(H) == pytest.approx(0.5, rel=0.01)
    norm = out["mean_curvature_normalized"]
    assert norm.min() == 0.0 and norm.max() == 1.0
    # downstream filters see the new arrays
    tri = vtkTriangleFilter()
    tri.SetInputConnection(alg.GetOutputPort())
    tri.Update()
    assert tri.GetOutput().GetPointData().GetArray("k1") is not None


def test_setters_modify_only_on_change():
    alg = Curvature()
    assert alg.GetOrientation() == "outward"
    t0 = alg.GetMTime()
    alg.SetOrientation("outward")
    assert alg.GetMTime() == t0
    alg.SetOrientation("keep")
    assert alg.GetMTime() > t0 and alg.GetOrientation() == "keep"
    with pytest.raises(ValueError, match="orientation must be one of"):
        alg.SetOrientation("left")
    with pytest.raises(TypeError, match="no option 'radius'"):
        Curvature(radius=1.0)


def test_errors_inside_request_data_reach_the_caller():
    alg = Curvature()
    with pytest.raises(InvalidMeshError, match="triangulate"):
        alg.run(pv.Plane())
    # the filter stays usable after an error
    out = pv.wrap(alg.run(pv.Sphere()))
    assert "mean_curvature" in out.point_data


def test_run_output_is_independent_of_later_updates():
    alg = Curvature()
    first = pv.wrap(alg.run(pv.Sphere(radius=1.0)))
    second = pv.wrap(alg.run(pv.Sphere(radius=4.0)))
    assert np.median(first["mean_curvature"]) == pytest.approx(1.0, rel=0.02)
    assert np.median(second["mean_curvature"]) == pytest.approx(0.25, rel=0.02)


def test_keep_orientation_reports_and_respects_winding():
    inward = pv.Sphere()
    inward = pv.PolyData(inward.points, np.c_[np.full(inward.n_cells, 3), inward.regular_faces[:, ::-1]].ravel())
    kept = pv.wrap(Curvature(orientation="keep").run(inward))
    fixed = pv.wrap(Curvature().run(inward))
    assert np.median(kept["mean_curvature"]) < 0 < np.median(fixed["mean_curvature"])
    assert kept.field_data["face_orientation"][0] == "keep"
    assert int(kept.field_data["flipped_faces"][0]) == 0
    assert int(fixed.field_data["flipped_faces"][0]) == inward.n_cells


def test_every_filter_declares_its_metadata():
    for cls in ALL_FILTERS:
        assert cls.LABEL and cls.__doc__
        for p in cls.PARAMS:
            assert p.doc and p.validate(p.default) == p.default
            assert hasattr(cls, f"Set{p.camel}") and hasattr(cls, f"Get{p.camel}")


@pytest.mark.parametrize("orientation", ["outward", "keep"])
@pytest.mark.parametrize("defect", ["nan point", "index past the points"])
def test_curvature_refuses_a_bad_surface_from_every_entry(orientation, defect):
    sphere = pv.Icosphere(nsub=2)
    points, faces = np.array(sphere.points, float), sphere.regular_faces.copy()
    if defect == "nan point":
        points[5, 1] = np.nan
        message = "NaN or infinite coordinates at 1 vertices"
    else:
        faces[7, 2] = len(points) + 3
        message = rf"vertex indices in \[0, {len(points) + 3}\] but the mesh has {len(points)} points"
    bad = pv.PolyData.from_regular_faces(points, faces)
    with pytest.raises(InvalidMeshError, match=message):
        pverosion.curvature(bad, orientation=orientation)
    assert_pipeline_keeps_the_error(Curvature(orientation=orientation), bad, message)
