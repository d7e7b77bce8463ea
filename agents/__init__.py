"""Controllers that act in the environments, the evaluation runner and the ``mrmt`` command."""
