"""Particle water: position-based fluids colliding with a triangle mesh (Macklin & Müller 2013).

:mod:`.params` (parameters, emitters, drains, states), :mod:`.grids` (hashed grids), :mod:`.collision`
(the mesh), :mod:`.pbf` (the solver's kernels) and :mod:`.particle_fluid` (the fluid that runs them).
"""

__all__: list[str] = []
