"""The move engine of the tour and the fleet search: one route form (:mod:`.routes`), one file per
move kind (:mod:`.kinds`: :mod:`.two_opt`, :mod:`.or_opt`, :mod:`.swap`, :mod:`.two_opt_star`), two
neighbourhoods (:mod:`.route_moves`, the tour's; :mod:`.granular`, the fleet's), one local search
(:mod:`.search`) and the chip's selection among the offered moves (:mod:`.selection`)."""
