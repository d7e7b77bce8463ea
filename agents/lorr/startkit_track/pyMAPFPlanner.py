"""The start kit's ``pyMAPFPlanner``: the package's planner (:class:`agents.lorr.startkit.KitPlanner`)."""

from agents.lorr.startkit import KitPlanner as pyMAPFPlanner  # noqa: F401
