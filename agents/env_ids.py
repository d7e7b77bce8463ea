"""Which registered env an id names (grid level or plan level), with a clear error for an unknown id."""

from __future__ import annotations

__all__ = ["check_env_id", "check_worlds", "is_assign_env", "is_lifelong_env"]


def check_env_id(env_id: str):
    """The id's ``gymnasium`` spec; ``ValueError`` listing the ``mrmt_env/`` ids if it is not registered."""
    import gymnasium as gym

    import mrmt_env  # noqa: F401  (registers the ids)

    if env_id not in gym.registry:
        known = ", ".join(sorted(k for k in gym.registry if k.startswith("mrmt_env/")))
        raise ValueError(f"unknown env id {env_id!r}; registered: {known}")
    if env_id in mrmt_env.LORR_IDS:
        raise ValueError(f"{env_id} runs League of Robot Runners instances: use mrmt lorr run INSTANCE.json")
    if not env_id.startswith("mrmt_env/"):
        raise ValueError(f"{env_id!r} is not an mrmt_env/ id; this command runs the package's envs")
    return gym.spec(env_id)


def is_assign_env(env_id: str) -> bool:
    """True for a plan-level (Assign) env id: an idle robot picks its next target."""
    entry = check_env_id(env_id).entry_point
    return isinstance(entry, str) and entry.endswith(":MRMTAssignEnv")


def is_lifelong_env(env_id: str) -> bool:
    """True for a lifelong env id (a task stream; a learned controller chooses each idle robot's next task)."""
    entry = check_env_id(env_id).entry_point
    return isinstance(entry, str) and entry.endswith(":MRMTLifelongEnv")


def check_worlds(env_id: str, env_kwargs: dict, seeds) -> None:
    """Build ``env_id`` with ``env_kwargs`` and reset it on every world seed of a run, so a world
    the env cannot hold (too many robots for the grid, a map too small for its layout) is a
    one-line ``ValueError`` before any progress bar or worker pool starts, not in the middle."""
    import gymnasium as gym

    check_env_id(env_id)
    try:
        env = gym.make(env_id, **env_kwargs)
    except (ValueError, TypeError) as exc:
        raise ValueError(" ".join(str(exc).split())) from None
    try:
        for seed in seeds:
            env.reset(seed=int(seed))
    except (ValueError, TypeError) as exc:
        raise ValueError(f"world seed {seed}: {' '.join(str(exc).split())}") from None
    finally:
        env.close()
