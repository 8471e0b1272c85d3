"""The two setups the study measures the findings under, side by side: the bench's (the charles_river library scenario
as it is) and the field study's own (its era's receiver and its Method 1 as the study ran it).

Only what the field study did differently changes; everything else (the world, the route, the LiDAR, Method 2, the
other matchers, the chained odometry, the compass) is the same measurement, shared by both setups.
"""

from __future__ import annotations

from dataclasses import dataclass, field

SETUP_NAMES = ("bench", "field")
"""Every setup, in report order."""
CHOICES = {"both": SETUP_NAMES, "bench": ("bench",), "field": ("field",)}
"""What `riverbench study --setup` takes and the setups each runs."""
FIELD_METHOD1_ID = "pcl6d_field"
"""The burst matcher id of Method 1 as the field study ran it (reported as pcl6d in the field setup's findings)."""


@dataclass(frozen=True)
class Setup:
    """One setup: its receiver (overrides of the scenario's [gnss] table) and Method 1's parameters (pcl6d's)."""

    name: str
    """bench or field."""
    description: str
    """What the setup is, in one sentence (the report says it)."""
    receiver: dict = field(default_factory=dict)
    """[gnss] fields written over the library scenario's (empty: the library's receiver, sbas with four systems)."""
    method1: dict = field(default_factory=dict)
    """pcl6d parameters of Method 1 (empty: pcl6d at its defaults, the bench's Method 1)."""
    judged_matchers: tuple[str, ...] | None = None
    """The matchers whose figures findings f and g judge (None: every matcher); the others are reported beside them."""


SETUPS: dict[str, Setup] = {
    "bench": Setup(
        "bench",
        "the charles_river library scenario as it is: the sbas receiver tracking GPS, GLONASS, Galileo and BeiDou; "
        "pcl6d at its defaults (pre-alignment only when scans are more than 0.25 s apart, two de-skew rounds)",
    ),
    "field": Setup(
        "field",
        "the field study's own setup: a receiver of its era (about 2016), the sbas class tracking GPS alone "
        "(profile sbas_gps, the Hemisphere V102's GPS L1 C/A; Galileo's services began in December 2016, BeiDou's "
        "global one in 2020; its carrier smoothing restarting at reacquisition); Method 1 as the study describes it, FPFH "
        "pre-alignment with correspondence rejection then ICP on every pair of scans (the bench's pcl6d skips the "
        "pre-alignment for scans 0.25 s apart or less), its RANSAC run as PCL's SampleConsensusPrerejective runs it: "
        "a fixed count of hypotheses, PCL's default 5,000, with no early exit at a confidence (Open3D's default stops there); "
        "its findings on matching (f, g) judged on its two methods, which are what it ran (kiss_icp and gicp reported beside)",
        receiver={"profile": "sbas_gps"},
        method1={"skip_prealign_max_dt_s": 0.0, "ransac_until": "max_iterations", "ransac_max_iterations": 5000},
        judged_matchers=("pcl6d", "bev3dof"),
    ),
}
"""The setups by name."""


def setup_method1(setup: str) -> str:
    """How the figures name a setup's Method 1 beside the first setup's pcl6d: 'pcl6d (field)'."""
    return f"pcl6d ({setup})"


def parse_setup(text: str) -> tuple[str, ...]:
    """The setups `--setup TEXT` runs (ValueError naming the value and the choices)."""
    if text not in CHOICES:
        raise ValueError(f"--setup {text!r}: unknown study setup; give one of {', '.join(CHOICES)}")
    return CHOICES[text]
