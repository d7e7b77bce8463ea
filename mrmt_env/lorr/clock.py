"""The start kit's clock (v2.1 ``BaseSystem::plan`` and ``simulate``): a time limit per step and one for preprocessing.

Contract: :class:`StepLimit` ``(step_s, preprocess_s)``; :meth:`StepLimit.timeouts` ``(decision_s) -> steps``.
The start kit waits for the entry's decision ``step_s`` at a time; each wait that ends without it is a step in
which every robot waits (``NA``, written ``T``, counted in ``numEntryTimeouts``), and the decision, once ready,
is executed from the unchanged state.  A decision of ``d`` seconds thus costs ``ceil(d / step_s) - 1`` timeouts
before it runs (none while ``d <= step_s``); timeouts that reach the end of the run end it.  Preprocessing
(reading, distance tables; not compilation, which is the entry's build) has its own limit; the start kit ends
a run whose preprocessing is late without a score.  ``step_limit("rules")`` is the rules' 1 s of 2023 and 2024.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["StepLimit", "step_limit", "RULES_STEP_S", "RULES_PREPROCESS_S"]

#: ``planTimeLimit`` of the 2023 and 2024 rounds: 1 s per step for scheduler and planner together.
RULES_STEP_S = 1.0
#: The start kit's default ``preprocessTimeLimit`` (30,000 ms).
RULES_PREPROCESS_S = 30.0


@dataclass(frozen=True)
class StepLimit:
    """Seconds per step (``step_s``) and for preprocessing (``preprocess_s``); see the module docstring."""

    step_s: float = RULES_STEP_S
    preprocess_s: float = RULES_PREPROCESS_S

    def __post_init__(self) -> None:
        for name in ("step_s", "preprocess_s"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                    or not 0 < value <= 3600:
                raise ValueError(f"{name} = {value!r} must be a number of seconds in (0, 3600]")

    def timeouts(self, decision_s: float) -> int:
        """Steps every robot waits before a decision of ``decision_s`` seconds is executed."""
        return max(math.ceil(decision_s / self.step_s) - 1, 0)

    def label(self) -> str:
        return f"{self.step_s:g} s per step"


def step_limit(text, preprocess_s: float = RULES_PREPROCESS_S) -> StepLimit:
    """``rules`` (the rounds' 1 s) or seconds per step, as a :class:`StepLimit`; ``ValueError`` naming the value."""
    if isinstance(text, str) and text.strip().lower() == "rules":
        return StepLimit(RULES_STEP_S, preprocess_s)
    try:
        seconds = float(text)
    except (TypeError, ValueError):
        raise ValueError(f"step limit {text!r} must be 'rules' (1 s) or seconds per step in (0, 3600]") from None
    if not 0 < seconds <= 3600:
        raise ValueError(f"step limit {text!r} must be 'rules' (1 s) or seconds per step in (0, 3600]")
    return StepLimit(seconds, preprocess_s)
