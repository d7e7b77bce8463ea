"""A faulty chip: the fault model (``model``) and graceful degradation (``health``)."""
