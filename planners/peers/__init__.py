"""Peer solvers: the classical solvers a user would pick for this problem, as planning layers.

``pyvrp_routing`` -- sharing and tours solved jointly by PyVRP (optional extra ``peers``:
``pip install 'mrmt-ising[peers]'``).  Nothing here is imported until a layer is asked for.
"""
