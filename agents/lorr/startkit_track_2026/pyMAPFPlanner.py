"""The 2026 start kit's ``python/user_planner/pyMAPFPlanner.py``: the package's one-step planner
(:class:`agents.lorr.startkit.KitPlanner2026`)."""

from agents.lorr.startkit import KitPlanner2026 as pyMAPFPlanner  # noqa: F401
