"""Subcommands of the ``mrmt`` command line (see :mod:`agents.cli`)."""
