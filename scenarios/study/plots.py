"""The study report's figures, one per finding (matplotlib Figures rendered by Agg, no pyplot), written atomically."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from riverbench.atomic import atomic_path
from scenarios.score import metrics
from scenarios.score import windows as win
from scenarios.study.gnss_findings import open_water, shadowed
from scenarios.study.matcher_findings import columns
from scenarios.study.plan import MATCHERS
from scenarios.study.setups import SETUP_NAMES, setup_method1

FILE_MODE = 0o644
DPI = 100
COLOURS = {"pcl6d": "#1f77b4", "bev3dof": "#d62728", "kiss_icp": "#2ca02c", "gicp": "#9467bd"} | {
    setup_method1(name): "#17becf" for name in SETUP_NAMES
}
"""Colours of the built-in matchers' marks, and of another setup's Method 1 beside the first setup's pcl6d."""
OTHER_COLOURS = ("#ff7f0e", "#8c564b", "#e377c2", "#bcbd22")
"""Colours of the command matchers' curves (the built-ins have theirs)."""
BESIDE = " With both setups, pcl6d (field) is the field setup's Method 1 (pre-aligned on every pair) beside the bench's."
"""What the matcher figures show beside the first setup's matchers."""
CAPTIONS = {
    "a": "Seconds without a measured fix (the run's blackout windows), at quality 0, and with fewer than 4 satellites in "
    "direct line of sight (the truth) around each structure, beside the time spent under its deck.",
    "b": "Horizontal error of the measured fixes after each outage against the time since it ended; dashed: open water's p95.",
    "c": "HDOP against the true horizontal error of each measured fix (orange: in an NLOS window); right: the ROC of HDOP as a "
    "detector of fixes off by more than 5 m, in the NLOS windows and over every measured fix.",
    "d": "Cumulative distribution of the open-water fixes' horizontal error (no facade reflection reaching the antenna); dashed: the study's 1 m.",
    "e": "Wall time of each registration against the points in the scan, per matcher; dashed: 1, 8 and 10 Hz." + BESIDE,
    "f": "Success rate per 1,000-point bin of points per scan, per matcher (bars: registrations per bin, right axis); "
    "shaded: the study's 6,000-27,000 band. A command matcher's (dashed): its steps over every revolution of the stretch, its "
    "own claim (a pose), and dotted the share of them within 5 cm and 0.5 deg of the true motion." + BESIDE,
    "g": "Share of points (or correspondences) each matcher rejected as outliers, per registration; dashed: the study's 10 %." + BESIDE,
    "h": "Yaw of the chained matcher odometry minus the truth along the stretch, beside the magnetic compass's heading error "
    "(dashed: a command matcher's odometry, every revolution, laid onto the truth at its first pose).",
}


def _figure(cols: int = 1, height: float = 3.6) -> tuple[Figure, list]:
    fig = Figure(figsize=(11.0, height), layout="constrained")
    return fig, [fig.add_subplot(1, cols, i + 1) for i in range(cols)]


def outages_figure(m: dict) -> Figure | None:
    s = m["structures"]
    if not s:
        return None
    fig, (ax,) = _figure()
    names = list(s)
    x = np.arange(len(names))
    for i, (key, label) in enumerate(
        (("passage_s", "under the deck"), ("blackout_s", "no measured fix"), ("quality0_s", "quality 0"), ("los_below_4_s", "< 4 in sight (truth)"))
    ):
        ax.bar(x + (i - 1.5) * 0.2, [s[n][key] or 0.0 for n in names], 0.2, label=label)
    ax.set_xticks(x, names, fontsize=8)
    ax.set_ylabel("s")
    ax.legend(fontsize=8)
    return fig


def after_outage_figure(gnss, m: dict) -> Figure | None:
    if not m["outages"]:
        return None
    f = gnss.fixes
    err = f.horizontal_error
    fig, (ax,) = _figure()
    for o in m["outages"]:
        sel = f.measured & (f.t >= o["end"]) & (f.t < o["end"] + 30.0)
        ax.plot(f.t[sel] - o["end"], err[sel], lw=1, alpha=0.8)
    if m["open_water_p95_m"] is not None:
        ax.axhline(m["open_water_p95_m"], ls="--", c="k", lw=1)
    ax.set_xlabel("s after the outage")
    ax.set_ylabel("horizontal error, m")
    return fig


def hdop_figure(gnss) -> Figure | None:
    f = gnss.fixes
    measured = f.measured
    if not measured.any():
        return None
    in_nlos = np.zeros(len(f.t), dtype=bool)
    for w in win.find(f, [], gnss.period_s):
        if w.kind == "nlos":
            in_nlos |= (f.t >= w.start) & (f.t < w.end)
    err = f.horizontal_error
    fig, (ax, roc_ax) = _figure(2)
    for sel, colour, label in ((measured & ~in_nlos, "#4d4d4d", "other fixes"), (measured & in_nlos, "#ff7f0e", "in NLOS windows")):
        ax.scatter(f.hdop[sel], err[sel], s=3, c=colour, label=label)
    ax.axhline(metrics.FAULT_M, ls=":", c="k", lw=1)
    ax.set_xlabel("HDOP")
    ax.set_ylabel("horizontal error, m")
    ax.set_yscale("symlog", linthresh=1.0)
    ax.legend(fontsize=8)
    for sel, colour, label in ((measured & in_nlos, "#ff7f0e", "in NLOS windows"), (measured, "#4d4d4d", "every measured fix")):
        faulty = err[sel] > metrics.FAULT_M
        if faulty.any() and (~faulty).any():
            fa, rec, _ = metrics.roc(f.hdop[sel], faulty)
            roc_ax.plot(np.r_[fa, 1.0], np.r_[rec, 1.0], c=colour, label=label)
    if roc_ax.lines:
        roc_ax.legend(fontsize=8)
    else:  # a stretch without a fix beyond the fault, or without a good one: no curve to draw
        roc_ax.text(
            0.5, 0.5, f"no ROC: the fixes are not both\nwithin and beyond {metrics.FAULT_M:g} m", ha="center", va="center", transform=roc_ax.transAxes
        )
    roc_ax.plot([0, 1], [0, 1], ls=":", c="k", lw=1)
    roc_ax.set_xlabel("false-alarm rate")
    roc_ax.set_ylabel("recall")
    return fig


def open_water_figure(gnss, mask: np.ndarray) -> Figure | None:
    err = np.sort(gnss.fixes.horizontal_error[mask])
    if not len(err):
        return None
    fig, (ax,) = _figure()
    ax.plot(err, np.arange(1, len(err) + 1) / len(err))
    ax.axvline(1.0, ls="--", c="k", lw=1)
    ax.set_xlabel("horizontal error, m")
    ax.set_ylabel("share of open-water fixes")
    return fig


def plotted(rows: list[dict]) -> list[str]:
    """The matchers the figures show: the built-ins, then another setup's Method 1 where its rows are there."""
    present = {row["matcher"] for row in rows}
    return [*MATCHERS, *(mid for mid in COLOURS if mid not in MATCHERS and mid in present)]


def beside(tree: dict, key: str) -> dict:
    """Finding `key`'s measured node of the first setup with each other setup's Method 1 (its pcl6d) added as
    'pcl6d (<setup>)' under its 'matchers' (finding f) or at the top (finding g)."""
    setups = list(tree.get("setups", {}))
    node = dict(tree["findings"][key]["measured"])
    for other in setups[1:]:
        theirs = tree["findings"][key]["setups"][other]["measured"]
        if key == "f":
            node["matchers"] = {**node["matchers"], setup_method1(other): theirs["matchers"]["pcl6d"]}
        else:
            node[setup_method1(other)] = theirs["pcl6d"]
    return node


def rates_figure(rows: list[dict]) -> Figure | None:
    if not rows:
        return None
    fig, (ax,) = _figure()
    for mid in plotted(rows):
        c = columns(rows, mid)
        reg = c["gated"] == 0
        ax.scatter(c["points"][reg], 1e3 * c["seconds"][reg], s=4, c=COLOURS.get(mid), label=mid)
    for hz in (1.0, 8.0, 10.0):
        ax.axhline(1e3 / hz, ls="--", c="k", lw=0.8)
    ax.set_yscale("log")
    ax.set_xlabel("points per scan")
    ax.set_ylabel("ms per registration")
    ax.legend(fontsize=8)
    return fig


def success_figure(m: dict) -> Figure | None:
    edges = np.asarray(m["bin_edges"], dtype=float)
    if len(edges) < 2:
        return None
    centres = (edges[:-1] + edges[1:]) / 2.0
    fig, (ax,) = _figure()
    counts = ax.twinx()
    width = (edges[1] - edges[0]) / (len(m["matchers"]) + 1)
    for i, (mid, s) in enumerate(m["matchers"].items()):
        rate = np.array([np.nan if v is None else v for v in s["success"]], dtype=float)
        colour = COLOURS.get(mid) or OTHER_COLOURS[i % len(OTHER_COLOURS)]
        ax.plot(centres, rate, marker="o", ms=3, c=colour, label=mid, ls="--" if mid not in COLOURS else "-")
        counts.bar(edges[:-1] + (i + 0.5) * width, s["count"], width, color=colour, alpha=0.25)
        if "accurate" in s:  # a command matcher: success is its own claim (a pose), so its accurate steps beside it
            accurate = np.array([np.nan if v is None else v for v in s["accurate"]], dtype=float)
            ax.plot(centres, accurate, ls=":", marker="x", ms=4, c=colour, label=f"{mid}: within {s['accurate_m']:g} m, {s['accurate_deg']:g} deg")
    ax.axvspan(*m["band"], color="#e6c229", alpha=0.15)
    ax.set_ylim(-0.05, 1.05)
    ax.set_xlabel("points per scan")
    ax.set_ylabel("success rate")
    counts.set_ylabel("registrations")
    ax.legend(fontsize=8, loc="center right")
    return fig


def outliers_figure(rows: list[dict], m: dict) -> Figure | None:
    data, labels = [], []
    for mid, node in m.items():
        c = columns(rows, mid)
        for key in node:
            v = 1.0 - c["inlier_share"] if key == "rejected_share" else c[key]
            data.append(v[np.isfinite(v)])
            labels.append(f"{mid}\n{key}")
    if not data:
        return None
    fig, (ax,) = _figure()
    ax.boxplot(data, tick_labels=labels, showfliers=False)
    ax.axhline(0.10, ls="--", c="k", lw=1)
    ax.set_ylabel("share rejected")
    ax.tick_params(axis="x", labelsize=7)
    return fig


def yaw_figure(m: dict, commands: list[dict] = ()) -> Figure | None:
    if not m["series"]["t"]:
        return None
    fig, (ax,) = _figure()
    ax.plot(m["series"]["t"], m["series"]["yaw_error_deg"], label=f"{m['matcher']} odometry")
    for c in commands:
        ax.plot(c["series"]["t"], c["series"]["yaw_error_deg"], ls="--", label=f"{c['matcher']} (command) odometry")
    ax.plot(m["compass_series"]["t"], m["compass_series"]["error_deg"], lw=0.8, label="magnetic compass")
    ax.set_xlabel("s")
    ax.set_ylabel("yaw error, deg")
    ax.legend(fontsize=8)
    return fig


def commands(tree: dict, key: str) -> list[dict]:
    """The command components' measured nodes in finding `key` (their first setup's: a matcher's steps are the same
    under every setup)."""
    return [next(iter(by_setup.values()))["measured"] for by_setup in tree["findings"][key].get("components", {}).values()]


def with_commands(m: dict, nodes: list[dict]) -> dict:
    """Finding f's node with the command matchers' curves beside the built-ins', on the longer of their bin edges."""
    if not nodes:
        return m
    edges = max([m["bin_edges"], *(n["bin_edges"] for n in nodes)], key=len)
    out = {**m, "bin_edges": edges, "matchers": {}}
    for mid, curve in [*m["matchers"].items(), *((f"{k} (command)", v) for n in nodes for k, v in n["matchers"].items())]:
        pad = len(edges) - 1 - len(curve["count"])
        out["matchers"][mid] = {**curve, "count": curve["count"] + [0] * pad, "success": curve["success"] + [None] * pad}
        if "accurate" in curve:
            out["matchers"][mid]["accurate"] = curve["accurate"] + [None] * pad
    return out


def write_all(plots_dir: Path, tree: dict, samples) -> dict[str, str]:
    """Every figure that has data, as plots/<key>_<name>.png; {finding key: path relative to the study directory}."""
    m = {k: v["measured"] for k, v in tree["findings"].items()}
    structures = samples.structures
    mask = open_water(samples.gnss, win.find(samples.gnss.fixes, [], samples.gnss.period_s), shadowed(structures), reflections=False)
    figures = {
        "a": outages_figure(m["a"]),
        "b": after_outage_figure(samples.gnss, m["b"]),
        "c": hdop_figure(samples.gnss),
        "d": open_water_figure(samples.gnss, mask),
        "e": rates_figure(samples.rows),
        "f": success_figure(with_commands(beside(tree, "f"), commands(tree, "f"))),
        "g": outliers_figure(samples.rows, beside(tree, "g")),
        "h": yaw_figure(m["h"], commands(tree, "h")),
    }
    plots_dir.mkdir(parents=True, exist_ok=True)
    out = {}
    for key, fig in figures.items():
        if fig is None:
            continue
        path = plots_dir / f"{key}.png"
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format="png", dpi=DPI)
        out[key] = f"plots/{key}.png"
    return out
