"""riverbench_plugins: an example package of riverbench plugins, registered by entry points in pyproject.toml.

- `icp2d` (riverbench.matchers): riverbench_plugins.icp2d:Icp2d, point-to-line ICP of the walls in the x-y plane.
- `complementary` (riverbench.estimators): riverbench_plugins.complementary:ComplementaryFilter.
- `jump` (riverbench.monitors): riverbench_plugins.jump:JumpMonitor, a fix-to-fix jump detector against the odometry.
"""
