"""Peer solvers: the classical solvers a user would pick for this problem, as planning layers.

``pyvrp_routing`` / ``ortools_routing`` -- sharing and tours solved jointly by PyVRP / OR-Tools
(optional extra ``peers``: ``pip install 'mrmt-ising[peers]'``); ``common`` -- their shared checks.  Nothing here is imported until a layer is asked for.
"""
