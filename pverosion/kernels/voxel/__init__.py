"""Voxel fields: Eulerian water on a MAC grid, its pressure solve, erosion at the interface, voxelisation (Beneš 2006)."""

__all__: list[str] = []
