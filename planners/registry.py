"""Planning-method registry: layer name -> factory, one namespace per layer (sharing, tour, path).

A factory is a callable or a ``"module:attr"`` string imported on first use; :func:`register_sharing`,
:func:`register_tour` and :func:`register_path` add a user's own, which then works wherever a name is accepted.
An unknown name raises :class:`UnknownPlannerError` listing the valid ones.
Design notes (the names): docs/design/pipeline.md#the-layer-registry.
"""

from __future__ import annotations

import importlib
import inspect
from collections.abc import Callable

__all__ = ["LAYERS", "UnknownPlannerError", "register", "register_path", "register_tour", "register_sharing",
           "names", "path_names", "tour_names", "sharing_names", "get_factory", "create", "accepts"]

LAYERS = ("sharing", "tour", "path")

_REGISTRY: dict[str, dict[str, Callable | str]] = {
    "sharing": {
        "round_robin": "planners.sharing_classical:RoundRobinSharing",
        "psa": "planners.sharing_classical:PSASharing",
        "ssa": "planners.sharing_classical:SSASharing",
        "exact": "planners.sharing_classical:ExactSharing",
        "ising": "planners.ising.sharing:IsingSharing",
        "ising-paper": "planners.ising.sharing:PaperIsingSharing",
        "pyvrp": "planners.peers.pyvrp_routing:PyVRPSharing",  # extra `peers`
        "ortools": "planners.peers.ortools_routing:ORToolsSharing",  # extra `peers`
        "ising-fleet": "planners.ising.fleet:IsingFleetSharing",
    },
    "tour": {
        "nn": "planners.tours_classical:NearestNeighbourTour",
        "2opt": "planners.tours_classical:TwoOptTour",
        "3opt": "planners.tours_classical:ThreeOptTour",
        "brute": "planners.tours_classical:BruteTour",
        "ising": "planners.ising.tour:IsingTour",
        "ising-paper": "planners.ising.tour:PaperIsingTour",
        "keep": "planners.joint_routing:KeepOrderTour",
    },
    "path": {
        "bfs": "planners.paths_classical:BFSPath",
        "astar": "planners.paths_classical:AStarPath",
        "gbfs": "planners.paths_classical:GreedyBestFirstPath",
        "ising": "planners.ising.path:IsingPath",
        "ising-paper": "planners.ising.path:PaperIsingPath",
        "field": "planners.paths_field:FieldPath",
    },
}


class UnknownPlannerError(ValueError):
    """A layer name that is not registered, or whose factory cannot be loaded."""


def _check_layer(layer: str) -> dict:
    if layer not in _REGISTRY:
        raise UnknownPlannerError(f"unknown planning layer {layer!r}; layers are {', '.join(LAYERS)}")
    return _REGISTRY[layer]


def register(layer: str, name: str, factory: Callable | str, replace: bool = False) -> None:
    """Register ``factory`` (callable or ``"module:attr"``) as ``name`` in ``layer``.

    Raises:
        ValueError: an empty or non-string name, a malformed ``"module:attr"``
            string, or a name already taken (unless ``replace=True``).
    """
    table = _check_layer(layer)
    if not isinstance(name, str) or not name or any(ch.isspace() or ch in "+=," for ch in name):
        raise ValueError(f"{layer} planner name must be a non-empty string without spaces, '+', '=' or ',', got {name!r}")
    if isinstance(factory, str):
        module, _, attr = factory.partition(":")
        if not module or not attr:
            raise ValueError(f"lazy factory must look like 'package.module:attr', got {factory!r}")
    elif not callable(factory):
        raise ValueError(f"factory for {layer} planner {name!r} must be callable or 'module:attr', got {factory!r}")
    if name in table and not replace:
        raise ValueError(f"{layer} planner {name!r} is already registered (pass replace=True to override)")
    table[name] = factory


def register_path(name: str, factory: Callable | str, replace: bool = False) -> None:
    """Register a pathfinding method (see :func:`register`)."""
    register("path", name, factory, replace)


def register_tour(name: str, factory: Callable | str, replace: bool = False) -> None:
    """Register a tour-construction method (see :func:`register`)."""
    register("tour", name, factory, replace)


def register_sharing(name: str, factory: Callable | str, replace: bool = False) -> None:
    """Register a target-sharing method (see :func:`register`)."""
    register("sharing", name, factory, replace)


def names(layer: str) -> tuple[str, ...]:
    """Registered names of ``layer`` (including lazy ones not yet imported)."""
    return tuple(_check_layer(layer))


def sharing_names() -> tuple[str, ...]:
    return names("sharing")


def tour_names() -> tuple[str, ...]:
    return names("tour")


def path_names() -> tuple[str, ...]:
    return names("path")


def get_factory(layer: str, name: str) -> Callable:
    """The factory registered as ``name`` in ``layer`` (lazy strings imported now).

    Raises:
        UnknownPlannerError: unknown name, or a lazy factory that cannot be
            imported (the message gives the import error and the valid names).
    """
    table = _check_layer(layer)
    valid = ", ".join(table)
    if name not in table:
        raise UnknownPlannerError(f"unknown {layer} planner {name!r}; valid {layer} planners: {valid}")
    factory = table[name]
    if isinstance(factory, str):
        module_name, _, attr = factory.partition(":")
        try:
            module = importlib.import_module(module_name)
            factory = getattr(module, attr)
        except (ImportError, AttributeError) as exc:
            raise UnknownPlannerError(
                f"{layer} planner {name!r} ({module_name}:{attr}) is unavailable: "
                f"{type(exc).__name__}: {exc}; valid {layer} planners: {valid}"
            ) from exc
        table[name] = factory
    return factory


def _option_names(factory: Callable) -> list[str]:
    """Keyword options of ``factory``: its named parameters, plus its ``config_class`` fields."""
    try:
        params = [p for p, v in inspect.signature(factory).parameters.items()
                  if p != "self" and v.kind is not inspect.Parameter.VAR_KEYWORD]
    except (TypeError, ValueError):  # pragma: no cover - builtins without signatures
        params = []
    cfg = getattr(factory, "config_class", None)
    return params + [f for f in getattr(cfg, "__dataclass_fields__", {}) if f not in params]


def accepts(factory: Callable, keyword: str) -> bool:
    """Whether ``factory`` takes keyword argument ``keyword``.

    A factory with a ``config_class`` (the Ising planners) takes its named
    parameters and that config's fields; any other ``**kwargs`` takes everything.
    """
    try:
        params = inspect.signature(factory).parameters
    except (TypeError, ValueError):  # pragma: no cover - builtins without signatures
        return False
    if keyword in params and params[keyword].kind in (
        inspect.Parameter.POSITIONAL_OR_KEYWORD,
        inspect.Parameter.KEYWORD_ONLY,
    ):
        return True
    if getattr(factory, "config_class", None) is not None:
        return keyword in _option_names(factory)
    return any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values())


def create(layer: str, name: str, options: dict | None = None, shared: dict | None = None):
    """Build the ``layer`` planner registered as ``name``.

    ``options`` are passed to the factory as keywords (an option it does not
    take raises ``ValueError`` naming the option and the accepted ones, as
    :meth:`planners.options.Options.from_dict` does);
    ``shared`` keywords (e.g. ``chip``) are passed only if the factory takes them.
    """
    factory = get_factory(layer, name)
    options = dict(options or {})
    for key in options:
        if not accepts(factory, key):
            allowed = _option_names(factory)
            raise ValueError(
                f"{layer} planner {name!r} takes no option {key!r}; its options: {', '.join(allowed) or 'none'}"
            )
    for key, value in (shared or {}).items():
        if key not in options and accepts(factory, key):
            options[key] = value
    return factory(**options)
