"""The start kit's roles (:mod:`mrmt_env.lorr.roles`: :class:`Scheduler`, :class:`Planner`) and the charge of a role
that may or may not account for its compute (:func:`charge`)."""

from __future__ import annotations

from mrmt_env.lorr.roles import Planner, Scheduler
from planners.compute import ComputeReport

__all__ = ["Scheduler", "Planner", "charge", "NO_CHARGE"]

#: The charge of a role without compute accounting: nothing beyond its measured host seconds.
NO_CHARGE = ComputeReport()


def charge(role) -> ComputeReport:
    """The role's last call's :class:`~planners.compute.ComputeReport` (:data:`NO_CHARGE` without accounting)."""
    return getattr(role, "last_compute", NO_CHARGE)
