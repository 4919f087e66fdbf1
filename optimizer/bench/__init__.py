"""The optimizer on the bench: one run of a scene on hardware (run), its objective, the bench study
with its simulated prior, and the --hardware options of `featherstar optimize`."""
