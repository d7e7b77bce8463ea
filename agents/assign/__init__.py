"""The plan-level (Assign) env's agents: a planner acting in it, the learned allocator and its decoding."""
