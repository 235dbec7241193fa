"""Exact geometry: robust predicates, triangle intersection, intersection curves, cutting triangles along them."""
