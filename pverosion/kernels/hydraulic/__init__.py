"""Hydraulic erosion of meshes by the particle fluid, and the overhang measure (Skorkovská 2019 §3.4, §4.2)."""

__all__: list[str] = []
