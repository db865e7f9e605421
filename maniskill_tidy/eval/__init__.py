"""Metrics, the resumable episode runner and the leaderboard."""
