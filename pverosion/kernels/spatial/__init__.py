"""Spatial queries on triangle meshes: bucket grids of boxes, triangle indices, inside/outside by rays."""

__all__: list[str] = []
