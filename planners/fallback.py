"""The classical fallback of a planning layer: the last resort of graceful degradation, in one place.

:func:`answer` (or :func:`fall_back` on a result in hand) is how the pipeline calls a layer: a failed call of a
layer whose ``config`` has a ``fallback`` mode (:data:`FALLBACK_MODES`: ``"never"``, ``"unavailable"`` by default,
``"failure"``) goes to the ``strong`` pipeline's classical layer, flagged and counted, never silently. Layers
themselves never fall back. Design notes: docs/design/faults.md#fallbacks-plannersfallbackpy.
"""

from __future__ import annotations

from dataclasses import replace

__all__ = ["FALLBACK_MODES", "METHODS", "answer", "fall_back", "flagged", "unavailable_message"]

FALLBACK_MODES = ("never", "unavailable", "failure")

#: each layer's planning method
METHODS = {"sharing": "assign", "tour": "solve", "path": "find_path"}


def unavailable_message(exc) -> str:
    return f"the chip could not answer: {exc}"


def _classical(layer: str):
    """The ``strong`` pipeline's layer of kind ``layer``."""
    if layer == "path":
        from planners.paths_classical import AStarPath

        return AStarPath()
    if layer == "tour":
        from planners.tours_classical import ThreeOptTour

        return ThreeOptTour()
    from planners.sharing_classical import SSASharing

    return SSASharing()


def _failed(layer: str, result) -> bool:
    return (result.path is None) if layer == "path" else (result.failure is not None)


def fall_back(layer: str, obj, args: tuple, result):
    """``result`` of ``obj``'s ``layer`` method on ``args`` or, where ``obj.config.fallback`` asks for it,
    the classical layer's answer on the same ``args``, flagged and counted (module docstring)."""
    if not _failed(layer, result):
        return result
    config = getattr(obj, "config", None)
    mode = getattr(config, "fallback", "never")
    unavailable = bool(result.stats.get("chip_unavailable"))
    if not (mode == "failure" or (mode == "unavailable" and unavailable)):
        return result
    classical = getattr(_classical(layer), METHODS[layer])(*args)
    if _failed(layer, classical):  # the classical layer fails too: the layer's own failure stands
        return result
    return flagged(layer, classical, result.failure, result.stats, result.compute + classical.compute)


def flagged(layer: str, result, reason: str, stats: dict | None = None, compute=None):
    """``result`` as one fallback of ``layer`` for ``reason``: ``stats`` (default: its own) and
    ``compute`` (default: its own) with the fallback flagged and counted."""
    stats = dict(result.stats if stats is None else stats)
    counts = stats["fallback"] = dict(stats.get("fallback", {}))
    counts[layer] = counts.get(layer, 0) + 1
    stats["fallback_reasons"] = [*stats.get("fallback_reasons", []), f"{layer}: {reason}"]
    compute = result.compute if compute is None else compute
    return replace(result, stats=stats, compute=compute.replace(fallbacks=compute.fallbacks + 1))


def answer(layer: str, obj, *args):
    """``obj``'s ``layer`` method (:data:`METHODS`) on ``args``, with its fallback (:func:`fall_back`)."""
    return fall_back(layer, obj, args, getattr(obj, METHODS[layer])(*args))
