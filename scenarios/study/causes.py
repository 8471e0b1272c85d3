"""Each finding's cause in one sentence with the measured numbers, next to its verdict: why the bench agrees with the
field study, or what makes it differ (a model's physics or the setup). The mechanisms named here were traced on the
whole route (seed 0; the report's numbers are the run's own) and each cites where it is documented."""

from __future__ import annotations

import math

from scenarios.study.setups import SETUPS
from scenarios.study.verdicts import SMOOTHING_MIN_S, WEAK_RHO


def _n(value, fmt: str = ".1f") -> str:
    return "n/a" if value is None or not (isinstance(value, (int, float)) and math.isfinite(value)) else format(value, fmt)


def _range(values: list[float], fmt: str = ".1f") -> str:
    finite = [v for v in values if v is not None and math.isfinite(v)]
    if not finite:
        return "n/a"
    lo, hi = f"{min(finite):{fmt}}", f"{max(finite):{fmt}}"
    return lo if lo == hi else f"{lo}-{hi}"


GLASSY_DEG = 0.01
"""The LiDAR tilting less than this between revolutions (median) is glassy water: a ring meets a wall 80 m off within
14 mm of where it met it a revolution earlier."""


def _tilt(tilt: dict | None) -> float:
    return math.nan if tilt is None else tilt["median"]


def _tilted(tilt: dict | None) -> bool:
    """Whether the vessel tilts between revolutions (waves), so that matching causes turn on it."""
    value = _tilt(tilt)
    return math.isfinite(value) and value >= GLASSY_DEG


def cause_a(setup: str, verdict: str, m: dict, tilt: dict | None = None) -> str:
    """a: which receiver holds or loses the fix under the decks, and the satellites in direct sight there."""
    s = m["structures"]
    held = [name for name, v in s.items() if not v["blackout_s"] > 0.0]
    lost = ", ".join(f"{name} {100 * v['lost_share_under']:.0f}%" for name, v in s.items())
    if not held:
        profile = SETUPS[setup].receiver.get("profile", "sbas")
        return f"Every deck cuts the fix ({profile}): share of the epochs under each without a measured fix: {lost}."
    sight = ", ".join(f"{name} {s[name]['los_min_under']}" for name in held)
    return (
        f"Under {', '.join(held)} the receiver keeps at least 4 satellites in direct sight through the passage (fewest: {sight}), "
        f"because it tracks GPS, GLONASS, Galileo and BeiDou; a receiver of the study's era tracked GPS alone (the field setup). "
        f"Epochs without a measured fix under each deck: {lost}."
    )


def cause_b(setup: str, verdict: str, m: dict, tilt: dict | None = None) -> str:
    """b: the wrong estimate is the receiver's coast and what re-acquisition gives; how fast the filter lets it go."""
    rows = m["outages"]
    if not rows:
        return "No outage of 1 s or more on the stretch."
    slow = [r for r in rows if math.isfinite(r["settle_s"]) and r["settle_s"] >= SMOOTHING_MIN_S]
    fast = [r for r in rows if r not in slow]
    coast = (
        f"the receiver's dead reckoning (GGA quality 6, constant velocity, sim.receiver_filter) ends "
        f"{_range([r['coast_end_error_m'] for r in rows])} m off"
    )
    lingering = (
        f"after {len(slow)} of {len(rows)} outages the first fixes, on {_range([r['first_sats'] for r in slow], '.0f')} "
        f"satellites, are off by up to {_range([r['first_max_m'] for r in slow])} m (the worst of each) and the filter takes "
        f"{_range([r['settle_s'] for r in slow])} s to bring the error within open water's p95 ({_n(m['open_water_p95_m'], '.2f')} m)"
    )
    quick = (
        f"after {len(fast)} of {len(rows)} outages (coasts of {_range([r['coasted_s'] for r in fast])} s on the straight "
        f"track) the fixes that follow replace the coast within {_range([r['settle_s'] for r in fast])} s: the filter's "
        f"covariance grew over the coast and 5 Hz fixes weighted with the profile's 0.4 m allowance pull it back in a few epochs"
    )
    if slow and SETUPS[setup].receiver.get("profile") == "sbas_gps":
        lingering += (
            " (its carrier smoothing restarts at reacquisition: the raw code's 0.6 m noise averaged down as 1/sqrt(epochs "
            "since lock), docs/models.md)"
        )
    if fast and setup == "field":
        quick += (
            "; real receivers' logs (tests/data/nmea) walk back over 8-13 s after acquisition, but none records a coast "
            "this short, and how a 2016 receiver weighted its first fix after one is not documented"
        )
    parts = [p for p, rows_ in ((lingering, slow), (quick, fast)) if rows_]
    return f"The wrong estimate: {coast}; " + "; ".join(parts) + f". What the first fixes are made of: {_first_fixes(setup, rows, m)}."


def _first_fixes(setup: str, rows: list[dict], m: dict) -> str:
    """b: how many outages end on fixes that use a satellite received only by its reflection (a deck's edge, a quay),
    against those that end on direct signals alone, and why a receiver tracking GPS alone meets fewer of them."""
    if any("first_reflected" not in r for r in rows):
        return "not recorded"
    reflected = [r for r in rows if r["first_reflected"] > 0]
    direct = [r for r in rows if r["first_reflected"] == 0]
    n = m.get("first_fixes", 10)
    text = (
        f"after {len(reflected)} of {len(rows)} outages some of the first {n} fixes use a satellite received only by its "
        f"reflection (the truth's NLOS flag; off by up to {_range([r['first_max_m'] for r in reflected])} m), after "
        f"{len(direct)} they use direct signals alone, on {_range([r['first_sats'] for r in direct], '.0f')} satellites "
        f"(off by up to {_range([r['first_max_m'] for r in direct])} m)"
    )
    if SETUPS[setup].receiver.get("profile") == "sbas_gps":
        text += (
            "; tracking GPS alone, fewer satellites reach the antenna at a deck's edge, by reflection too, so the fix "
            "mostly comes back when enough are in direct sight"
        )
    return text


def cause_c(setup: str, verdict: str, m: dict, tilt: dict | None = None) -> str:
    """c: HDOP follows the geometry of the satellites used, not the reflections' range bias."""
    return (
        f"HDOP is computed from the geometry of the satellites used, not from their range errors: a reflected signal "
        f"adds its extra path to the range and leaves the geometry, so the {m['faulty_fixes']} fixes reflections put "
        f"more than {m['fault_m']:g} m off have a median HDOP of {_n(m['faulty_hdop_median'], '.2f')} against open water's "
        f"p95 {_n(m['open_water_hdop_p95'], '.2f')} (Spearman {_n(m['spearman_nlos'], '.2f')})."
    )


def cause_d(setup: str, verdict: str, m: dict, tilt: dict | None = None) -> str:
    """d: the receiver's own open-water error, and where facade reflections on direct signals add to it."""
    w = m["with_reflections"]
    where = " to ".join(w.get("between") or []) or "n/a"
    lo_hi = w.get("added_stations_m") or [math.nan, math.nan]
    text = (
        f"Where no facade reflection reaches the antenna the error is the receiver's own (p95 {_n(m['error']['p95'], '.2f')} m, "
        f"open-sky p95 {_n(m['open_sky_error']['p95'], '.2f')} m, the {SETUPS[setup].receiver.get('profile', 'sbas')} "
        f"profile's datasheet 0.9 m); counted with the fixes whose direct signals also carry a reflection's code error "
        f"(code multipath, docs/models.md 'GNSS'), p95 is {_n(w['error']['p95'], '.2f')} m: "
        f"{100 * _f(w['added_share']):.0f}% of those fixes, between stations {_n(lo_hi[0], '.0f')}-{_n(lo_hi[1], '.0f')} m "
        f"(from {where}: the lower basin, its quays and buildings), are moved more than 0.5 m (p95 {_n(w['added_p95_m'], '.2f')} m)"
    )
    return text + "."


def _f(value) -> float:
    return float(value) if value is not None and math.isfinite(value) else math.nan


def cause_e(setup: str, verdict: str, m: dict, tilt: dict | None = None) -> str:
    """e: what sets Method 1's rate (its pre-alignment or not) and both methods' precision."""
    p, b = m.get("pcl6d", {}), m.get("bev3dof", {})
    precision = (
        f"Method 1's median error {_n(p.get('error_m_median'), '.3f')} m against Method 2's {_n(b.get('error_m_median'), '.3f')} m "
        f"(Method 2's 0.3 m pixels; its 45 m image leaves {100 * _f(b.get('unresolved')):.0f}% unresolved where the banks are "
        f"60-100 m off; pcl6d's normals were fitted to one ring until ac22f24, docs/models.md)"
    )
    if setup == "bench":
        rate = (
            f"pcl6d skips its FPFH pre-alignment between revolutions 0.1 s apart and runs ICP from the motion prior alone, "
            f"so it runs at {_n(p.get('hz'))} Hz and its time hardly follows the points (Spearman of its CPU time "
            f"{_n(p.get('spearman_cpu_seconds_points'), '.2f')})"
        )
    else:
        rho = p.get("spearman_cpu_seconds_points")
        rate = (
            f"with the FPFH pre-alignment on every pair and PCL's fixed 5,000 RANSAC hypotheses (SampleConsensusPrerejective "
            f"has no early exit; each hypothesis is scored on every feature correspondence, so the time follows the "
            f"points: Spearman of its CPU time {_n(p.get('spearman_cpu_seconds_points'), '.2f')}), as the study ran it, "
            f"Method 1 takes {_n(p.get('ms_median'), '.0f')} ms ({_n(p.get('hz'))} Hz; {_n(p.get('cpu_hz'))} Hz by its CPU "
            f"time, this machine, not the study's 2016 laptop)"
        )
        if rho is not None and math.isfinite(rho) and rho <= WEAK_RHO:
            rate += (
                f", but its time follows the points only weakly (Spearman {_n(rho, '.2f')}): the route's scans span a narrow "
                f"range of points (median {_n(p.get('points_median'), '.0f')})"
            )
    return f"{rate}; {precision}."


def cause_f(setup: str, verdict: str, m: dict, tilt: dict | None = None) -> str:
    """f: how many registrations fall below the band and how they fare, and what the bench's crowns lack."""
    parts = ", ".join(f"{mid} {100 * _f(v['below_success']):.0f}% of {v['below_count']}" for mid, v in m["matchers"].items() if v["below_count"])
    lo = m["band"][0]
    head = (
        f"Most of the route's scans have fewer than {lo:,} points (the basin's banks and walls 60-100 m off, almost nothing "
        f"from the water, docs/models.md 'Points per revolution'), and "
    )
    if _tilted(tilt):
        return head + (
            f"in the chop the LiDAR tilts {_n(tilt['median'], '.2f')} deg (median, p90 {_n(tilt['p90'], '.2f')}) between "
            f"revolutions 0.1 s apart, so a ring meets a wall 80 m off decimetres higher or lower each time and finds no "
            f"partner there ({parts} succeed by the matchers' own fitness and plausibility tests): sparse scans are far "
            f"scans, where a tilt moves the points most (docs/models.md 'Glassy water')."
        )
    return head + (
        f"they still match ({parts} succeed by the matchers' own fitness and plausibility tests): on glassy water (the "
        f"LiDAR tilts {_n(_tilt(tilt), '.2f')} deg between revolutions) two revolutions 0.1 s apart cross every surface "
        f"along the same lines, and the tree crowns that give about half of those scans' points echo from 1.5 m facets that "
        f"repeat like walls. The basin's chop at Boston's mean wind (--set vessel.wind_waves, docs/models.md 'Glassy water') "
        f"makes pcl6d fail below the band as the study's Method 1 did, but in the band too, and its outlier share then "
        f"overshoots the study's; every leaf echo drawn afresh (lidar.foliage_echo = 'leaves') does the same (docs/models.md "
        f"'Foliage echoes'): the water and the crowns of the study's day are what the bench does not know."
    )


def cause_g(setup: str, verdict: str, m: dict, tilt: dict | None = None) -> str:
    """g: the outlier shares the matchers report."""
    parts = "; ".join(f"{mid} {k} {100 * s['median']:.1f}%" for mid, node in m.items() for k, s in node.items())
    parts = parts or "none reported"
    if _tilted(tilt):
        return (
            f"In the chop the LiDAR tilts {_n(tilt['median'], '.2f')} deg (median) between revolutions, so the rings of "
            f"consecutive scans cross distant surfaces along other lines and more points find no partner: {parts}."
        )
    return f"Consecutive revolutions overlap almost entirely and the simulated surfaces are exact, so few points find no partner: {parts}."


def cause_h(setup: str, verdict: str, m: dict, tilt: dict | None = None) -> str:
    """h: the chained matcher's heading drift beside the compass."""
    return (
        f"{m['matcher']}'s steps each carry a small yaw error that integrates without a bound over the route "
        f"({_n(m['drift_end_deg'])} deg after {_n(m['distance_m'], '.0f')} m, the largest {_n(m['drift_max_deg'])} deg), while "
        f"the compass's error is bounded (p95 {_n(m['compass_p95_deg'])} deg)."
    )


CAUSES = {"a": cause_a, "b": cause_b, "c": cause_c, "d": cause_d, "e": cause_e, "f": cause_f, "g": cause_g, "h": cause_h}
"""Each finding's cause, by key."""


def cause(key: str, setup: str, verdict: str, m: dict, tilt: dict | None = None) -> str:
    """The finding's cause in one sentence with the numbers measured under `setup`; `tilt`: how far the LiDAR tilts
    between consecutive revolutions (matcher_findings.tilt_change), which the matching findings' causes turn on."""
    try:
        return CAUSES[key](setup, verdict, m, tilt)
    except (KeyError, TypeError, ValueError, IndexError):  # a short stretch lacks a figure: say so, never fail the study
        return "not enough data on this stretch to name the cause."
