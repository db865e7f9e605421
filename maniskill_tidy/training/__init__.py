"""Demonstrations for imitation learning (and, later, behaviour cloning)."""
