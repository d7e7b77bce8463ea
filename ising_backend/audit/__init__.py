"""What the chip is worth per decision: the decision audit (``record``), its judge (``judge``) and the host-rule
ablation (``host_rule``)."""
