"""The emulated CMOS Ising chip, the logical Ising solver and the mapping toolkit.

Knows Ising models and hardware, not robots: imports no other project package.
"""
