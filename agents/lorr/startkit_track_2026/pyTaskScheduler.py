"""The 2026 start kit's ``python/user_scheduler/pyTaskScheduler.py``: the package's scheduler
(:class:`agents.lorr.startkit.KitScheduler`)."""

from agents.lorr.startkit import KitScheduler as pyTaskScheduler  # noqa: F401
