"""The start kit's ``pyTaskScheduler``: the package's scheduler (:class:`agents.lorr.startkit.KitScheduler`)."""

from agents.lorr.startkit import KitScheduler as pyTaskScheduler  # noqa: F401
