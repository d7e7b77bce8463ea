"""The classical fallback of a planning layer: the last resort of graceful degradation, in one place.

Contract: :func:`answer` (or :func:`fall_back` on a result in hand) is how the pipeline calls a
layer.  A layer that offers a fallback has a ``fallback`` mode in its ``config``
(:data:`FALLBACK_MODES`); when its result fails and the mode asks for it, the call goes to the
classical layer of the ``strong`` pipeline -- path: A*, tour: 3-opt, sharing: SSA -- with the
same arguments, and never silently: the result's stats get ``stats["fallback"][layer] += 1`` and a
line in ``stats["fallback_reasons"]``, its compute report ``fallbacks += 1``, and the chip calls
spent before the fallback stay charged.  A failure the classical layer shares (an unreachable goal)
stays the layer's own failure.  The modes:

* ``"never"``: no fallback; an unavailable chip is a failure result, as any failure;
* ``"unavailable"`` (default): only when the chip could not answer (the layer's result says so
  with ``stats["chip_unavailable"]``);
* ``"failure"``: also when the layer's own search fails (no valid decode within its budgets).

Layers themselves never fall back: an Ising layer called on its own returns its failure.
Design notes: docs/design/faults.md.
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
