"""The lifelong envs: tasks keep arriving; Gymnasium, PettingZoo, native vector env."""
