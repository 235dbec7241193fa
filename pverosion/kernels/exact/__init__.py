"""Exact geometry: robust predicates, triangle intersection, intersection curves, cutting triangles along them."""

__all__: list[str] = []
