"""The PIBT family: grid PIBT (``grid``), PIBT with turning for the League's action model (``turning``), and
windowed prioritized space-time A* on the grid (``windowed``)."""

