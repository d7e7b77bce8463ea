"""The one-step planners that leave a decision to an Ising machine: the groups' joint next moves of ``pibt-ising``
(``joint_moves``, ``joint_executor``) and the neighbourhoods' operation choices of ``epibt-ising``
(``epibt_ising``, ``choice_qubo``)."""
