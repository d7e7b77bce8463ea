"""Host-rule ablation: a decision class's programs answered by the host rule instead of the machine.

Contract: inside ``with HostRule({"sharing_split"}):`` (or ``HostRule("all")``) every submission of a named
decision class takes :func:`ising_backend.audit.judge.greedy_descent`'s answer on the host, the same for
every read and charged nothing to the machine; ``joint_moves``, ``lns_groups`` and ``task_groups``
take their planners' and scheduler's own host rules.  Closed, nothing changes.  Usage: docs/audit.md; design:
docs/design/machine_link.md.
"""

from __future__ import annotations

import numpy as np

__all__ = ["HostRule", "host_rule_classes", "host_answer", "HOST_RULE_CLASSES", "GENERIC_CLASSES"]

#: The decision classes whose programs the generic host rule answers.
GENERIC_CLASSES = ("path_query", "sharing_split", "tour_split", "tour_order", "tour_moves", "fleet_moves")
#: Every class a host rule can take: the generic ones, then the executors' classes with host rules of their own.
HOST_RULE_CLASSES = GENERIC_CLASSES + ("joint_moves", "lns_groups", "task_groups")
_ACTIVE: list[frozenset] = []


def host_rule_classes() -> frozenset:
    """The classes the innermost open :class:`HostRule` names (empty when none is open)."""
    return _ACTIVE[-1] if _ACTIVE else frozenset()


def parse_classes(spec) -> frozenset:
    """``"all"``, a comma-separated string or an iterable of class names as a set; ``ValueError`` naming
    an unknown class and the known ones."""
    names = spec.split(",") if isinstance(spec, str) else list(spec)
    names = [n.strip() for n in names if n.strip()]
    if names == ["all"]:
        return frozenset(HOST_RULE_CLASSES)
    unknown = [n for n in names if n not in HOST_RULE_CLASSES]
    if unknown or not names:
        raise ValueError(f"unknown host-rule class(es) {unknown or names}; known: {', '.join(HOST_RULE_CLASSES)} "
                         "or all")
    return frozenset(names)


class HostRule:
    """While open, the named classes' programs get the host rule's answer (module docstring)."""

    def __init__(self, classes) -> None:
        self.classes = parse_classes(classes)

    def __enter__(self) -> "HostRule":
        _ACTIVE.append(self.classes)
        return self

    def __exit__(self, *exc) -> None:
        _ACTIVE.pop()


def host_answer(h, J, num_reads: int) -> tuple[np.ndarray, np.ndarray]:
    """``(spins (B, num_reads, n) int8, energies (B, num_reads))`` of programs ``h (B, n)``, ``J (B, n, n)``
    (``J (n, n)`` with ``h (B, n)``: shared by the B programs; one program: ``h (n,)``, ``J (n, n)`` gives ``(num_reads, n)`` and ``(num_reads,)``): the host
    rule's answer repeated over the reads."""
    from ising_backend.audit.judge import greedy_descent

    h, J = np.asarray(h, dtype=np.float64), np.asarray(J, dtype=np.float64)
    single = h.ndim == 1
    if single:
        h, J = h[None], J[None]
    elif J.ndim == 2:
        J = np.broadcast_to(J, (h.shape[0],) + J.shape)
    spins = np.empty((h.shape[0], num_reads, h.shape[1]), dtype=np.int8)
    energies = np.empty((h.shape[0], num_reads))
    for b in range(h.shape[0]):
        e, s = greedy_descent(np.ascontiguousarray(h[b]), np.ascontiguousarray(J[b]))
        spins[b] = s.astype(np.int8)
        energies[b] = e
    return (spins[0], energies[0]) if single else (spins, energies)
