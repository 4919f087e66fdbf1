"""Scenes as data and the plan made of them: block specs, block kinds, the Scene, and plan()
(validation, pruning, deduplication, loops, step guards, preflight checks). No FMU binary is
loaded here."""
