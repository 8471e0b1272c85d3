"""The field study's findings, the one place their text and figures live; the study measures each on the bench.

The figures are the study's (what the bench is compared with), never the bench's: those are measured at run time.
"""

from __future__ import annotations

from dataclasses import dataclass, field

CITATION = (
    "Field study of LiDAR-aided positioning on an autonomous surface vessel (a WAM-V like the REx IV, top-mounted Velodyne "
    "HDL-32E) on the Charles River, Boston, between the BU Bridge and the Charlestown Bridge, as riverbench's design "
    "(DESIGN.md, 'The field study it reproduces') and issue 24 state its findings."
)
"""How the report cites the study."""


@dataclass(frozen=True)
class Finding:
    """One finding: its key (a-h), a short title, the study's claim in words and its figures by name."""

    key: str
    title: str
    claim: str
    figures: dict = field(default_factory=dict)


FINDINGS: tuple[Finding, ...] = (
    Finding("a", "GPS blackout under each bridge", "GPS drops out under the bridges."),
    Finding(
        "b",
        "the receiver's filter smooths a wrong fix after an outage",
        "After an outage the receiver's internal filter smooths an incorrect estimate for a while.",
    ),
    Finding(
        "c",
        "HDOP does not flag multipath",
        "Near walls, multipath gives wrong fixes while HDOP stays low: HDOP is not a reliable fault indicator.",
    ),
    Finding("d", "GPS below 1 m in open water", "In open water the GPS error stays below 1 m.", {"open_water_error_m": 1.0}),
    Finding(
        "e",
        "Method 1 at 1-8 Hz; Method 2 at >= 10 Hz, less precise, more unresolved",
        "Method 1 (6-DoF: filter, FPFH pre-alignment with correspondence rejection, ICP) ran at 1-8 Hz on a laptop, its rate "
        "depending on the points per scan; Method 2 (3-DoF image registration) ran at >= 10 Hz with lower precision and "
        "more unresolved matches.",
        {"method1_hz": (1.0, 8.0), "method2_min_hz": 10.0},
    ),
    Finding(
        "f",
        "matching succeeds for 6,000-27,000 points per scan",
        "Matching succeeded for 6,000-27,000 points per scan and failed mostly below.",
        {"points_band": (6000, 27000)},
    ),
    Finding("g", "under 10% of points rejected as outliers", "Under 10% of the points were rejected as outliers.", {"outlier_share": 0.10}),
    Finding(
        "h",
        "matcher-only yaw drifts 20 deg over the route",
        "Yaw from scan matching alone drifted 20 degrees by the route's end (against the compass).",
        {"yaw_drift_deg": 20.0},
    ),
)
"""The findings, in report order."""


def by_key() -> dict[str, Finding]:
    """The findings by key."""
    return {f.key: f for f in FINDINGS}
