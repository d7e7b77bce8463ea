"""The modules the League's start kit imports by name (its ``config.json`` ``python_path`` names this folder)."""
