"""Many runs: the suite, sweeps (plan, table, plots, progress) on local processes or Ray."""
