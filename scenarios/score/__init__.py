"""What a run is judged by: per-scan records, GPS-degradation windows, metrics, expectations, baselines and their comparison."""
