"""Shared machinery of the stages that move the vertices of a closed mesh step by step (the erosion guard)."""

__all__: list[str] = []
