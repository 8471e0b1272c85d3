"""What a person reads: the run report, the comparison report, plots, terminal tables, generated results."""
