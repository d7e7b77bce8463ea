"""Moves of the tour and the fleet search and the chip's selection among them."""
