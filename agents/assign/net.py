"""A set-suited policy for ``MRMT-Assign-v0``: a distance-biased attention encoder and a pointer head.

Tokens are the env's targets and robots; attention logits get a learned multiple of minus their BFS distance, the
pointer head scores each target against the deciding robot's context, stop has its own logit, a critic MLP reads
the same context. Needs torch and sb3-contrib (the ``rl`` extra); imported only to build or load a model.
Design notes: docs/design/learned-agents.md#the-pointer-policy.
"""

from __future__ import annotations

import math

import torch
from torch import nn
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from sb3_contrib.common.maskable.policies import MaskableActorCriticPolicy

__all__ = ["AssignEncoder", "PointerHead", "AssignPointerPolicy", "N_BASE_FEATURES"]

#: Feature columns before the per-target distance block (mrmt_env.assign.kernels.N_ROBOT_FEATURES).
N_BASE_FEATURES = 8
_DECIDER_COL = 6


class _BiasedAttention(nn.Module):
    def __init__(self, d_model: int, n_heads: int) -> None:
        super().__init__()
        self.n_heads, self.d_head = n_heads, d_model // n_heads
        self.qkv = nn.Linear(d_model, 3 * d_model)
        self.out = nn.Linear(d_model, d_model)
        # distance weights start spread over heads (one head nearly distance-blind)
        self.dist_w = nn.Parameter(torch.linspace(0.0, 4.0, n_heads))

    def forward(self, h: torch.Tensor, dist: torch.Tensor) -> torch.Tensor:
        b, t, d = h.shape
        q, k, v = self.qkv(h).view(b, t, 3, self.n_heads, self.d_head).permute(2, 0, 3, 1, 4)
        scores = q @ k.transpose(-1, -2) / math.sqrt(self.d_head)
        scores = scores - self.dist_w.view(1, -1, 1, 1) * dist.unsqueeze(1)
        att = torch.softmax(scores, dim=-1)
        return self.out((att @ v).transpose(1, 2).reshape(b, t, d))


class _Block(nn.Module):
    def __init__(self, d_model: int, n_heads: int) -> None:
        super().__init__()
        self.ln1, self.ln2 = nn.LayerNorm(d_model), nn.LayerNorm(d_model)
        self.att = _BiasedAttention(d_model, n_heads)
        self.ff = nn.Sequential(nn.Linear(d_model, 2 * d_model), nn.ReLU(), nn.Linear(2 * d_model, d_model))

    def forward(self, h, dist):
        h = h + self.att(self.ln1(h), dist)
        return h + self.ff(self.ln2(h))


class AssignEncoder(BaseFeaturesExtractor):
    """Tokens ``(B, N + R, 8 + N)`` -> flat ``(B, (N + R + 2) * d)``: every token's
    embedding, then the deciding robot's and the mean embedding (the context)."""

    def __init__(self, observation_space, d_model: int = 64, n_heads: int = 4, n_layers: int = 2) -> None:
        t, f = observation_space.shape
        self.n_tokens, self.n_targets = t, f - N_BASE_FEATURES
        super().__init__(observation_space, features_dim=(t + 2) * d_model)
        self.d_model = d_model
        self.embed = nn.Linear(f, d_model)
        self.blocks = nn.ModuleList(_Block(d_model, n_heads) for _ in range(n_layers))
        self.ln = nn.LayerNorm(d_model)

    def token_distances(self, x: torch.Tensor) -> torch.Tensor:
        """``(B, T, T)`` distances between tokens (robot-robot pairs: 0)."""
        n = self.n_targets
        dist = x.new_zeros(x.shape[0], self.n_tokens, self.n_tokens)
        block = x[:, :, N_BASE_FEATURES:]  # (B, T, N): distance from each token to each target
        dist[:, :, :n] = block
        dist[:, :n, n:] = block[:, n:, :].transpose(1, 2)
        return dist

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        dist = self.token_distances(x)
        h = self.embed(x)
        for blk in self.blocks:
            h = blk(h, dist)
        h = self.ln(h)
        decider = x[:, self.n_targets:, _DECIDER_COL].unsqueeze(-1)  # (B, R, 1) one-hot
        ctx = (h[:, self.n_targets:] * decider).sum(dim=1)
        return torch.cat([h.flatten(1), ctx, h.mean(dim=1)], dim=1)


class PointerHead(nn.Module):
    """Actor: ``N + 1`` logits (targets by pointer attention, then stop); critic: a ``d`` latent."""

    def __init__(self, n_tokens: int, n_targets: int, d_model: int, clip: float = 10.0) -> None:
        super().__init__()
        self.n_tokens, self.n_targets, self.d, self.clip = n_tokens, n_targets, d_model, clip
        self.latent_dim_pi = n_targets + 1
        self.latent_dim_vf = d_model
        self.query = nn.Linear(2 * d_model, d_model)
        self.key = nn.Linear(d_model, d_model)
        self.stop = nn.Sequential(nn.Linear(2 * d_model, d_model), nn.ReLU(), nn.Linear(d_model, 1))
        self.critic = nn.Sequential(nn.Linear(2 * d_model, d_model), nn.ReLU(), nn.Linear(d_model, d_model), nn.ReLU())

    def _split(self, features):
        tokens = features[:, : self.n_tokens * self.d].view(-1, self.n_tokens, self.d)
        ctx = features[:, self.n_tokens * self.d:]
        return tokens, ctx

    def forward_actor(self, features: torch.Tensor) -> torch.Tensor:
        tokens, ctx = self._split(features)
        q = self.query(ctx).unsqueeze(1)  # (B, 1, d)
        k = self.key(tokens[:, : self.n_targets])  # (B, N, d)
        logits = (q * k).sum(-1) / math.sqrt(self.d)
        logits = self.clip * torch.tanh(logits / self.clip)
        return torch.cat([logits, self.stop(ctx)], dim=1)

    def forward_critic(self, features: torch.Tensor) -> torch.Tensor:
        return self.critic(self._split(features)[1])

    def forward(self, features: torch.Tensor):
        return self.forward_actor(features), self.forward_critic(features)


class LogitsPolicy(MaskableActorCriticPolicy):
    """A masked actor-critic whose extractor's policy latent *is* the action logits (pointer style):
    the action net is the identity."""

    def _build(self, lr_schedule) -> None:
        super()._build(lr_schedule)
        self.action_net = nn.Identity()
        self.optimizer = self.optimizer_class(self.parameters(), lr=lr_schedule(1), **self.optimizer_kwargs)


class AssignPointerPolicy(LogitsPolicy):
    """sb3-contrib maskable actor-critic with :class:`AssignEncoder` and :class:`PointerHead`.

    The actor latent already is the logits, so the action net is the identity.
    """

    def __init__(self, observation_space, action_space, lr_schedule, d_model: int = 64, n_heads: int = 4,
                 n_layers: int = 2, **kwargs) -> None:
        self.d_model = d_model
        kwargs.setdefault("features_extractor_class", AssignEncoder)
        kwargs.setdefault("features_extractor_kwargs", dict(d_model=d_model, n_heads=n_heads, n_layers=n_layers))
        kwargs.setdefault("ortho_init", False)
        super().__init__(observation_space, action_space, lr_schedule, **kwargs)

    def _build_mlp_extractor(self) -> None:
        t, f = self.observation_space.shape
        self.mlp_extractor = PointerHead(t, f - N_BASE_FEATURES, self.d_model)

    def _get_constructor_parameters(self) -> dict:
        data = super()._get_constructor_parameters()
        data.update(d_model=self.d_model)
        return data
