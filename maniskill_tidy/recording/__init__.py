"""rerun recordings (.rrd) of episodes, replayed offline with ``maniskill-tidy replay``."""
