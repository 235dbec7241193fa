"""Repair of self-intersecting meshes and Boolean operations (thesis §10.2–10.3)."""

__all__: list[str] = []
