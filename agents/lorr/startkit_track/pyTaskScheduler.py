"""The start kit's ``pyTaskScheduler``: the package's scheduler (:class:`agents.lorr.startkit.KitScheduler`)."""

try:  # the kit's own binding: it registers the SharedEnvironment type the kit hands to this class
    import MAPF  # noqa: F401
except ImportError:  # outside the kit (the tests' stand-in)
    pass

from agents.lorr.startkit import KitScheduler as pyTaskScheduler  # noqa: F401
