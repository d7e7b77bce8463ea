"""The modules the League's 2026 start kit (v3.1) imports by name from its ``python/user_planner`` and
``python/user_scheduler`` folders (copy these two files over the kit's)."""
