"""The EPIBT family: PIBT over multi-action operations and its joint plans (``plans``), and the operations'
conflicts and large-neighbourhood search (``search``)."""
