"""`riverbench study`: the field study's findings (scenarios.study.findings) set beside the bench's measurements on the
charles_river route, each with a verdict; plan, per-finding measurements, verdict rules and the report, one module each."""
