"""The plan-level (Assign) envs: idle robots pick targets; Gymnasium, PettingZoo, native vector env."""
