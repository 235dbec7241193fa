"""Triangle-mesh basics: topology, orientation, geometry, Laplacian, remeshing, degenerate faces, terrain blocks."""

__all__: list[str] = []
