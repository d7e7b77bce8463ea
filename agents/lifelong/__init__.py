"""Controllers of the lifelong envs: assignment on events, the learned choice, evaluation, watching."""
