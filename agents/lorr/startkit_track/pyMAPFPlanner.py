"""The start kit's ``pyMAPFPlanner``: the package's planner (:class:`agents.lorr.startkit.KitPlanner`)."""

try:  # the kit's own binding: it registers the SharedEnvironment type the kit hands to this class
    import MAPF  # noqa: F401
except ImportError:  # outside the kit (the tests' stand-in)
    pass

from agents.lorr.startkit import KitPlanner as pyMAPFPlanner  # noqa: F401
