"""Learned agents: training with stable-baselines3 / sb3-contrib, and loading policies from files."""
