"""Shipped training configurations (one per mini-game; see docs/training.md)."""
