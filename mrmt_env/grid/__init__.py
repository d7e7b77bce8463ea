"""The MRMT grid envs (the paper's setting): Gymnasium, PettingZoo and the native vector env."""
