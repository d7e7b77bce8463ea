"""A pointer-style policy for the lifelong task choice: one shared scorer per candidate task.

The observation of :mod:`agents.lifelong.choice` is ``N_CANDIDATES`` rows of
``N_FEATURES`` numbers.  The actor scores every row with the same small MLP
(the logit of candidate ``j`` depends on row ``j`` only, so the rule learnt
for one candidate applies to all, whatever their order); the mask is applied
by sb3-contrib's ``MaskableCategorical``.  The critic is an MLP on all rows.
torch and sb3-contrib are needed (the ``rl`` extra).
"""

from __future__ import annotations

from torch import nn

from agents.assign.net import LogitsPolicy
from agents.lifelong.choice import N_CANDIDATES, N_FEATURES

__all__ = ["CandidateScorer", "LifelongTaskPolicy"]


class CandidateScorer(nn.Module):
    """Actor: ``N_CANDIDATES`` logits from one shared row scorer; critic: an ``hidden``-wide latent."""

    def __init__(self, hidden: int = 32) -> None:
        super().__init__()
        self.latent_dim_pi = N_CANDIDATES
        self.latent_dim_vf = hidden
        self.score = nn.Sequential(nn.Linear(N_FEATURES, hidden), nn.Tanh(), nn.Linear(hidden, hidden), nn.Tanh(),
                                   nn.Linear(hidden, 1))
        self.critic = nn.Sequential(nn.Linear(N_CANDIDATES * N_FEATURES, 2 * hidden), nn.Tanh(),
                                    nn.Linear(2 * hidden, hidden), nn.Tanh())

    def forward_actor(self, features):
        return self.score(features.view(-1, N_CANDIDATES, N_FEATURES)).squeeze(-1)

    def forward_critic(self, features):
        return self.critic(features)

    def forward(self, features):
        return self.forward_actor(features), self.forward_critic(features)


class LifelongTaskPolicy(LogitsPolicy):
    """sb3-contrib maskable actor-critic with :class:`CandidateScorer` (the actor latent is the logits)."""

    def __init__(self, observation_space, action_space, lr_schedule, hidden: int = 32, **kwargs) -> None:
        self.hidden = hidden
        kwargs.setdefault("ortho_init", False)
        super().__init__(observation_space, action_space, lr_schedule, **kwargs)

    def _build_mlp_extractor(self) -> None:
        self.mlp_extractor = CandidateScorer(self.hidden)

    def _get_constructor_parameters(self) -> dict:
        data = super()._get_constructor_parameters()
        data.update(hidden=self.hidden)
        return data
