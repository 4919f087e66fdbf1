"""Calibration: fitting drag, added-mass and hinge coefficients to recorded bench runs (recordings,
playback of the recorded root angle, the fit, `featherstar calibrate`)."""
