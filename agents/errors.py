"""Errors shared by the agents modules (kept apart so no two modules import each other)."""

from __future__ import annotations

__all__ = ["ControllerError"]


class ControllerError(ValueError):
    """A controller spec that names no known controller, or a model file that cannot be used."""
