"""The compiled PCG64 draws (mrmt_env.pcg64) against numpy's own, draw for draw."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from mrmt_env.fast_generation import draw_world_arrays
from mrmt_env.generation import generate_world
from mrmt_env.pcg64 import MAX_POP, bounded32, choice_floyd, next32, next64, state_views


def _pair(seed: int, odd_half: bool):
    a, b = np.random.default_rng(seed), np.random.default_rng(seed)
    if odd_half:  # leave a buffered 32-bit half waiting in both
        a.integers(0, 2**32, dtype=np.uint32)
        b.integers(0, 2**32, dtype=np.uint32)
    return a, b


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**63 - 1), pop=st.integers(1, MAX_POP), frac=st.floats(0, 1), odd=st.booleans())
def test_choice_matches_numpy_and_leaves_the_same_state(seed, pop, frac, odd):
    a, b = _pair(seed, odd)
    size = int(frac * pop)
    ref = a.choice(pop, size=size, replace=False)
    state, buf = state_views(b)
    out = np.empty(size, dtype=np.int64)
    choice_floyd(state, buf, pop, size, out)
    assert np.array_equal(out, ref)
    assert b.bit_generator.state == a.bit_generator.state
    assert b.random() == a.random()


@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 2**63 - 1), odd=st.booleans(), bound=st.integers(1, 2**32 - 2))
def test_raw_and_bounded_draws_match_numpy(seed, odd, bound):
    a, b = _pair(seed, odd)
    state, buf = state_views(b)
    assert int(next32(state, buf)) == int(a.integers(0, 2**32, dtype=np.uint32))
    assert int(next64(state)) == int(a.bit_generator.random_raw())
    # numpy's bounded uint32 fill draws through the same next_uint32 + Lemire path
    assert int(bounded32(state, buf, bound)) == int(a.integers(0, bound + 1, dtype=np.uint32))
    assert b.bit_generator.state == a.bit_generator.state


def test_other_bit_generators_are_left_to_numpy():
    assert state_views(np.random.Generator(np.random.Philox(3))) is None
    rng = np.random.Generator(np.random.Philox(3))
    params = dict(height=10, width=10, n_robots=3, n_targets=10, obstacle_density=0.2, placement="uniform")
    flat, robots, targets = draw_world_arrays(rng, params)
    w = generate_world(np.random.Generator(np.random.Philox(3)), **{k: v for k, v in params.items()})
    assert np.array_equal(flat, w.grid.reshape(-1)) and np.array_equal(robots, w.robots[:, 0] * 10 + w.robots[:, 1])


def test_compiled_world_draws_equal_generate_world_for_many_seeds():
    for h, w_, dens, r, n in ((10, 10, 0.2, 3, 10), (5, 5, 0.04, 2, 3), (32, 32, 0.3, 5, 40), (7, 13, 0.45, 1, 2)):
        params = dict(height=h, width=w_, n_robots=r, n_targets=n, obstacle_density=dens, placement="uniform")
        for seed in range(60):
            rng_a, rng_b = np.random.default_rng(seed), np.random.default_rng(seed)
            flat, robots, targets = draw_world_arrays(rng_a, params)
            world = generate_world(rng_b, **params)
            assert np.array_equal(flat, world.grid.reshape(-1))
            assert np.array_equal(robots, world.robots[:, 0] * w_ + world.robots[:, 1])
            assert np.array_equal(targets, world.targets[:, 0] * w_ + world.targets[:, 1])
            assert rng_a.random() == rng_b.random()
