"""Running a plan: the Simulator, the strong (one ODE, CVODE) and weak (Jacobi, Gauss-Seidel)
couplings, the schedule, the compiled right-hand side, start at rest and wall-clock pacing."""
