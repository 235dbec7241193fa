"""Particle water: position-based fluids colliding with a triangle mesh (Macklin & Müller 2013)."""

__all__: list[str] = []
