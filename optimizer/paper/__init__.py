"""The paper's reproduction: the plan of Figs. 3 and 5-9, running it, its figures and the report with
the claims table."""
