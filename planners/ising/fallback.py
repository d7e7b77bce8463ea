"""Classical fallbacks of the Ising layers: the last resort of graceful degradation.

Contract: an Ising layer whose chip cannot answer (:class:`ising_backend.ChipUnavailableError`)
hands the call to the classical layer of the ``strong`` pipeline -- path: A*, tour: 3-opt,
sharing: SSA -- and never silently: the result's stats get ``stats["fallback"][layer] += 1``
and a line in ``stats["fallback_reasons"]``, and its compute report ``fallbacks += 1`` (the
chip calls spent before the fallback stay charged).  Each Ising config's ``fallback``
option (:data:`FALLBACK_MODES`) chooses when:

* ``"never"``: no fallback; an unavailable chip is a failure result, as any failure;
* ``"unavailable"`` (default): only when the chip cannot answer;
* ``"failure"``: also when the Ising search itself fails (no valid decode within its
  budgets); a failure the classical layer shares (an unreachable goal) stays a failure.

Design notes: docs/design/faults.md.
"""

from __future__ import annotations

__all__ = ["FALLBACK_MODES", "flag", "counted", "wants_fallback", "fallen", "path_fallback", "unavailable_message"]

FALLBACK_MODES = ("never", "unavailable", "failure")


def unavailable_message(exc) -> str:
    return f"the chip could not answer: {exc}"


def wants_fallback(mode: str, unavailable: bool) -> bool:
    """Whether a failed layer call falls back under ``mode`` (``unavailable``: the chip could not answer)."""
    return mode == "failure" or (mode == "unavailable" and unavailable)


def flag(stats: dict, layer: str, reason: str) -> dict:
    """Record one fallback of ``layer`` (with its reason) in ``stats`` (in place; returned)."""
    fb = stats.setdefault("fallback", {})
    fb[layer] = fb.get(layer, 0) + 1
    stats.setdefault("fallback_reasons", []).append(f"{layer}: {reason}")
    return stats


def counted(compute, classical=None):
    """``compute`` with one more fallback, plus the classical layer's own report."""
    out = compute.replace(fallbacks=compute.fallbacks + 1)
    return out if classical is None else out + classical


def fallen(layer: str, classical, stats: dict, compute, reason: str):
    """The classical layer's result ``classical`` as ``layer``'s fallback: ``stats`` flagged (in place) with
    ``reason``, ``compute`` (what the Ising layer spent) counted plus the classical layer's own report."""
    from dataclasses import replace

    return replace(classical, stats=flag(stats, layer, reason), compute=counted(compute, classical.compute))


def path_fallback(mode: str, world, start, goal, rng, result):
    """The Ising path ``result`` or, when ``mode`` wants it, A*'s path flagged as a fallback."""
    if result.failure is None or not wants_fallback(mode, bool(result.stats.get("chip_unavailable"))):
        return result
    from planners.paths_classical import AStarPath

    classical = AStarPath().find_path(world, start, goal, rng)
    if classical.path is None:  # the classical layer fails too (e.g. an unreachable goal)
        return result
    return fallen("path", classical, dict(result.stats), result.compute, result.failure)
