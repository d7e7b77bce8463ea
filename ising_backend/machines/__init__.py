"""The machines: the interface and drivers (``base``, ``machine``, ``composite``, ``sampler_options``), the emulated
chip and its annealing kernel (``chip``, ``anneal``), the logical solver (``logical``, ``tabu``), the compiled loops'
way to any of them (``link``) and the checks every machine applies to a program (``programs``)."""
