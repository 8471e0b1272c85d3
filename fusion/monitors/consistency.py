"""Monitor 'consistency': GPS displacement against scan-matching displacement, with a re-acquisition guard.

Two tests, each a 2-dof Mahalanobis distance of (GPS displacement - odometry displacement) with
both covariances (GPS from HDOP, odometry from the matcher's covariances chained, rotated into the
world by the filter's heading with its variance):
- window: against the fix about `window_s` earlier; differencing cancels a slowly varying bias and
  catches a multipath jump at its onset.
- reference: against a reference antenna track that only trusted fixes update and the odometry
  carries between fixes (a small Kalman filter of its own, independent of the host filter), so a
  bias that persists after its onset stays flagged and one leaked fix barely moves the reference.
  Without a trusted fix for `reference_max_age_s` the reference is dropped and rebuilt.
Guard: after a stretch of at least `gap_s` without a measured fix (a blackout; start-up too with `startup_guard`), the
receiver's own filter may carry a wrong estimate that it smooths back slowly; fixes stay
untrusted until `guard_n` consecutive fixes pass both tests at the tighter `guard_gate_prob` gate
(the receiver's track moves with the odometry again and agrees with the reference; only a fix
with a window test, half a window after the gap or later, is evidence: the reference alone, carried
over the outage as uncertain as the dead reckoning, passes a walk-back's first metres), and for at
least `guard_s` (0 by default: the evidence ends it).
After a stretch of at least `refused_s` in which every fix failed these tests, the host has dead-reckoned as through a
blackout and the receiver may be walking back from the fault it carried, while the reference, carried as long, has
grown as loose as the walk-back: until a fix passes, it also needs the guard's evidence, its own track steady over the
window (against the fix there, whatever its verdict: the anchors there are fixes refused on C/N0 during the fault, which
carry it) and the reference within the guard's tighter gate (a walk-back of a metre a second or more fails it; a good
fix passes with the gate's probability, 0.9), and its track moving with the receiver's own velocity over ground (Doppler,
RMC; the odometry where a fix gives none) against every kept fix of the last `walk_window_s` since its last jump: a
filter walking back that overshoots turns smoothly, and at its turn stands still against the vessel over one window
while over its half-life it does not (quickstart seed 4 at 1785.7 s, 10.3 m off); a jump is the output taking the
measurements again, so the track before it is no evidence of a walk now.
The window test for the verdict uses trusted fixes only, so the end of a fault is
not mistaken for a jump; the guard's uses any fix, since none is trusted during the guard. Where the window holds no
anchor (every fix there refused on this monitor's tests), the verdict's window test is against the fix there all the
same: a receiver whose filter walks back from a reflected fix moves its output metres per second against the vessel's
motion, while the reference, carried for tens of seconds along a quay where the odometry is degenerate, is as uncertain
as that walk-back (quickstart at 1782.1 s, seed 0: a fix 18.5 m off passed the reference test at 3.4 sigma, the
reference's along-quay sigma 5.5 m after 19 s without an anchor, and the ekf moved 4.4 -> 19.4 m off; the fix had
moved 16 m more than the vessel in the 2 s before). The price: where a fault ends with a jump back, the first good fixes
are refused until the fix a window earlier is a good one (about window_s).
The window test compares with the fix about `window_s` earlier that was trusted or refused only on its own evidence
(an NLOS C/N0: its position is still a measurement): a receiver whose filter smooths a reflected signal into a ramp of
metres per second shows the ramp in consecutive fixes while a suspect-satellite monitor may flag some and miss others
(quickstart at 1764.7 s: 12.9 m and rising 8 m/s, trusted because every earlier fix had been refused on C/N0 and the
window held no trusted one). The price: the first good fix after a fault refused on C/N0 alone is refused for up to
twice `window_s`, as it jumps back.
Where the odometry leaves a direction unobserved (a degenerate match between walls or along a quay keeps a prior of its
own there, and the filter gives that direction 1e6 m^2), both tests take the displacement there as the constant-velocity
extrapolation of the host filter's velocity, uncertain by a speed error growing from the last trusted fix plus the motion
model's acceleration (see _moved and _cap); with 1e6 m^2 a receiver's ramp along a quay passed both, and with the
matcher's own prior a boat the matcher never saw move was held to stand still. The price: where the vessel changes speed while
the match is degenerate, the extrapolation errs and good fixes are refused until the re-lock (canal_multipath).
Every fix that passed both tests updates the reference, those refused only on their own evidence (C/N0) included: a
receiver whose every fix carries a weak satellite (tree-lined banks) still gets one, and the bound stays that of a
recently anchored track.
Steady (Verdict.steady): the fix's displacement from the fix a window earlier passes the guard's tight gate; the host
counts only steady refused fixes towards a re-lock, so it never re-locks onto a receiver's ramp.
Two fixes dt apart have errors correlated by rho = exp(-dt / correlation_s) (the host's
gps_correlation_s), so their displacement's noise is (C_a + C_b)(1 - rho), floored; the
reference weighs each trusted fix as a share dt / correlation_s of an independent one.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from scipy.stats import chi2

from fusion.geometry import drot2, rot2
from fusion.monitors.base import FixContext, Monitor, mahalanobis2
from fusion.monitors.track_noise import TrackNoise
from fusion.observation import FixObservation
from fusion.verdict import Verdict


class ConsistencyParams(BaseModel):
    """Parameters of the 'consistency' monitor: window and reference displacement tests and the re-acquisition guard."""

    model_config = ConfigDict(extra="forbid")
    window_s: float = Field(2.0, gt=0, description="the window test compares a fix with the fix about this long earlier, s [2]")
    gate_prob: float = Field(0.999, gt=0.5, lt=1.0, description="chi-square (2 dof) probability of both tests' gate [0.999, gate at 13.8]")
    reference_max_age_s: float = Field(60.0, gt=0, description="the reference is dropped and rebuilt after this long without a trusted fix, s [60]")
    gap_s: float = Field(
        2.0, gt=0, description="a stretch at least this long without a measured fix (a blackout, or start-up) starts the guard, s [2]"
    )
    guard_s: float = Field(
        0.0,
        ge=0,
        description="fixes stay untrusted for at least this long after such a gap, s [0: the evidence alone ends the guard, "
        "guard_n consecutive fixes whose window test passes the guard gate (and the reference test where there is one), "
        "i.e. the receiver's own track moves with the odometry again; a receiver still walking back moves against it. A "
        "fixed 5 s wait refused fixes that already passed while the host dead-reckoned on (quickstart [fast] seed 0: a "
        "step past the deck's edge took the ekf 3.8 m off during it); docs/models.md 'A guard that waits for evidence, "
        "not time']",
    )
    refused_s: float = Field(
        2.0,
        gt=0,
        description="after a stretch at least this long in which every fix failed this monitor's tests, a fix also needs "
        "the guard's evidence (steady over the window, the reference within guard_gate_prob) until one passes, s [2, as "
        "gap_s: the host has dead-reckoned as long as through a blackout, the reference has grown as loose, and the "
        "receiver that carried the fault may be walking back from it: quickstart seed 4 at 1771.9 s, after 20 s of "
        "refusals, a fix 25 m off passed the window test at 13.5 (walking back 1.5 m/s) and the reference at its "
        "along-quay sigma of 11 m, and the ekf went 5.5 -> 29.9 m off; docs/models.md 'Evidence after a refused stretch']",
    )
    walk_window_s: float = Field(
        4.0,
        gt=0,
        description="after such a refused stretch a fix must also have moved as the receiver's own velocity over ground "
        "says (its Doppler, RMC; the odometry where a fix gives none) since every kept fix from this long to half a window "
        "earlier, whatever their verdicts, back to the receiver's last jump, s [4: a consumer receiver's filter halves a "
        "fault's effect on its output in about 4 s (the cn0 monitor's hold). A filter that overshoots as it walks back "
        "stands still against the vessel at the overshoot's turn for about a window: quickstart seed 4 at 1785.7 s, 33 s "
        "into the refused stretch, the output turned "
        "10.3 m off after moving 9 m against the vessel in 5.6 s, passed the 2 s test at 4.1 under the guard's gate with "
        "the reference 6 m uncertain along the quay, and the ekf went 0.1 -> 8.8 m off. docs/models.md 'Evidence after "
        "a refused stretch']",
    )
    doppler_sigma_mps: float = Field(
        0.06,
        gt=0,
        description="per-axis sigma of the receiver's velocity over ground, taken as one error over a walk window (its "
        "slowly varying part does not average out), m/s [0.06, the ekf's gps_velocity_sigma_mps: sim.doppler's range "
        "rates, centimetres a second, through an open-water geometry]",
    )
    walk_noise_learned: bool = Field(
        True,
        description="the walk test judges the receiver's displacement against its velocity with the spread of its own "
        "clean track, learned from the fixes the host trusted (fusion.monitors.track_noise: the normal-consistent median "
        "absolute deviation per axis of the residual over 1 s, scaled as the square root of the lag), once 50 are "
        "learned [True: the host's error model "
        "(HDOP x UERE correlated over gps_correlation_s, floored at min_diff_sigma_m) is 4 times looser than the "
        "simulated receiver's clean track, and a walk-back's tail turning at 0.9 m/s passed it (the full quickstart, "
        "seed 0, 1790.0 s: 1.8 m against the Doppler over 4 s, 4.5 under the gate's 4.6; the ekf 2.2 -> 4.5 m off). "
        "False: the error model, as before]",
    )
    startup_guard: bool = Field(
        False,
        description="the guard also runs from the first fix and after a reset (the host's re-lock) [False: only after an "
        "outage, or from the first fix when the host started from a given pose (FixContext.own_start), where it carries "
        "a position of its own that a receiver's walk-back could drag away. Otherwise at start-up it has none: it "
        "initialises on the fixes whatever the verdict (fusion.bootstrap), so the "
        "guard refused only fixes it could not use yet (library [fast], seed 0: every trajectory byte-identical with and "
        "without it) and a receiver converging after acquisition walks towards the truth; it was 4-14% of each "
        "stretch's good fixes, a quarter of the ekf's false alarms; docs/models.md 'Which test refuses the good fixes'. "
        "True: as before]",
    )
    guard_n: int = Field(
        5, ge=0, description="during the guard, fixes also stay untrusted until this many consecutive ones pass both tests under the guard gate [5]"
    )
    guard_gate_prob: float = Field(
        0.9, gt=0.5, lt=1.0, description="chi-square (2 dof) probability of the tighter gate during the guard [0.9, gate at 4.6]"
    )
    max_speed_mps: float = Field(5.0, gt=0, description="bounds the unknown motion where the odometry does not cover a step, m/s [5]")
    unobserved_speed_sigma_mps: float = Field(
        0.3,
        gt=0,
        description="where the odometry leaves a direction unobserved (a degenerate match keeps its constant-velocity prior "
        "there, with a variance of 1e6 m^2 for the filter), its displacement over dt is taken as that extrapolation, "
        "uncertain by this speed error times dt plus the motion model's white acceleration, m/s [0.3: the speed a filter "
        "holds from GPS and odometry before the degeneracy]",
    )
    accel_sigma: float = Field(
        0.2,
        gt=0,
        description="white acceleration of the motion model bounding an unobserved direction's displacement (variance "
        "accel_sigma^2 dt^3 / 3), m/s^2/sqrt(Hz) [0.2: the ekf's and pf's own accel_sigma]",
    )
    min_diff_sigma_m: float = Field(
        0.3,
        gt=0,
        description="floor of the per-axis noise of a GPS displacement, whose noise is (C_a + C_b)(1 - rho) for two fixes "
        "dt apart with errors correlated by rho = exp(-dt / correlation_s), m [0.3]",
    )


class _Pending(NamedTuple):
    """What check decided about a fix, for commit to apply once the host's verdict on it is known."""

    gap: bool  # the fix ends a stretch without measured fixes (the guard starts)
    ref: tuple | None  # the reference carried to this fix
    evidence: bool | None  # the guard's evidence (None: no window test yet)
    weight: float  # the fix's share of an independent one, for the reference update
    failed: bool  # failed this monitor's tests (or, after a refused stretch, the guard's evidence): the stretch goes on


class ConsistencyMonitor(Monitor):
    """GPS-vs-odometry displacement tests plus the re-acquisition guard; statistic is the larger distance."""

    name = "consistency"

    def __init__(self, params: ConsistencyParams) -> None:
        self.params = params
        self.gate = float(chi2.ppf(params.gate_prob, 2))
        self.guard_gate = float(chi2.ppf(params.guard_gate_prob, 2))
        self._track_noise = TrackNoise()  # a property of the receiver: kept when the host re-locks, as cn0's template
        self.reset()

    def reset(self) -> None:
        self._history: deque[tuple[FixObservation, str]] = deque()  # recent fixes and verdicts: trusted, own (refused on its own evidence), refused
        self._ref: tuple[float, np.ndarray, np.ndarray] | None = None  # stamp, antenna xy, 2x2 cov
        self._ref_trusted_at = -math.inf
        self._last_measured: float | None = None
        self._guard_start: float | None = None
        self._guard_passes = 0
        self._refused_since: float | None = None  # first fix of the current stretch that failed this monitor's tests
        self._pending = _Pending(False, None, None, 1.0, False)

    def _moved(self, t_a: float, t_b: float, ctx: FixContext, since: float | None = None) -> tuple[np.ndarray, np.ndarray] | None:
        """Antenna displacement from t_a to t_b in the world by the odometry, and its 2x2 covariance; `since` (default t_a):
        when the track being carried was last anchored by a fix, from which an unobserved direction's speed error grows.
        Along a direction the odometry leaves unobserved the displacement is the filter's velocity times the time (see
        _cap): a degenerate matcher's own prior there is a guess of its own, and one that never saw the motion says
        the vessel stands still (rough_water's first 200 m of canal: gicp constrains height alone, its prior 0.04 m/s while
        the boat makes 2 m/s, and the monitor refused 77% of fixes good to 0.5 m)."""
        moved = ctx.odometry.displacement(t_a, t_b, ctx.lever)
        if moved is None or ctx.yaw is None:
            return None
        d_odo, cov_odo, odo_yaw = moved
        offset = ctx.yaw - odo_yaw
        rot = rot2(offset)
        j_yaw = drot2(offset) @ d_odo
        d_world, cov_world = rot @ d_odo, rot @ cov_odo @ rot.T
        values, vectors = np.linalg.eigh(0.5 * (cov_world + cov_world.T))
        cap = np.full(2, self._cap(t_a, t_b, t_a if since is None else since))
        if ctx.velocity_cov is not None:  # the host's own velocity uncertainty, where it exceeds the motion model's
            cap = np.maximum(cap, np.einsum("ji,jk,ki->i", vectors, ctx.velocity_cov, vectors) * (t_b - t_a) ** 2)
        if ctx.velocity is not None:
            for i in np.flatnonzero(values > cap):
                u = vectors[:, i]
                d_world = d_world + u * float(u @ (ctx.velocity * (t_b - t_a) - d_world))
        cov_world = (vectors * np.minimum(values, cap)) @ vectors.T
        return d_world, cov_world + np.outer(j_yaw, j_yaw) * (ctx.yaw_var or 0.0)

    def _cap(self, t_a: float, t_b: float, since: float) -> float:
        """The largest variance a direction's displacement from t_a to t_b gets (at least, in _moved, the host filter's own
        velocity variance along it times the time squared: a velocity the filter took from one wrong match and has not
        seen confirmed since is as uncertain as the filter says, quickstart seed 4 at 2006.5 s: gicp measured 5.6 m/s
        for 2.3 m/s after its chain restarted, the ekf kept 3.7 +- 1.3 m/s for 40 s while every slower match counted as
        a slip, and this cap of 0.3 m/s refused every good fix as too slow: 84 m off): that of a constant-velocity extrapolation
        (a degenerate match's prior along a wall or under a deck; the filter's 1e6 m^2 there would blind both tests in
        that direction, and a receiver's NLOS ramp along a quay passed them: quickstart at 1762 s, 2 m/s along the wall,
        reference sigma 950 m). The speed error's share grows with the time since the carried track was anchored, so a
        reference carried step by step gets the (sigma_v (t_b - since))^2 and accel_sigma^2 (t_b - since)^3 / 3 a single
        carry would."""
        p = self.params
        speed = p.unobserved_speed_sigma_mps**2 * ((t_b - since) ** 2 - (t_a - since) ** 2)
        accel = p.accel_sigma**2 * ((t_b - since) ** 3 - (t_a - since) ** 3) / 3.0
        return max(speed, 0.0) + max(accel, 0.0)

    def _distance(self, ref: FixObservation, obs: FixObservation, ctx: FixContext) -> float:
        """Mahalanobis distance squared of the GPS displacement from ref to obs against the odometry's."""
        moved = self._moved(ref.stamp, obs.stamp, ctx)
        if moved is None:
            return math.nan
        r = (obs.xy - ref.xy) - moved[0]
        return mahalanobis2(r, moved[1] + self._gps_difference(ref, obs, ctx))

    def _gps_difference(self, a: FixObservation, b: FixObservation, ctx: FixContext) -> np.ndarray:
        """2x2 noise of the receiver's displacement from fix a to fix b: (C_a + C_b)(1 - rho), their errors correlated by
        rho = exp(-dt / correlation_s), plus the floor min_diff_sigma_m per axis."""
        rho = math.exp(-(b.stamp - a.stamp) / ctx.correlation_s) if ctx.correlation_s > 0 else 0.0
        return (a.cov + b.cov) * (1.0 - rho) + np.eye(2) * self.params.min_diff_sigma_m**2

    def _walk(self, obs: FixObservation, ctx: FixContext) -> float:
        """The largest Mahalanobis distance squared of the receiver's displacement since each kept fix from walk_window_s
        to half a window earlier against its own velocity over ground integrated from there (trapezoids over the kept
        fixes; the odometry's displacement where a fix gives no velocity): a walk-back turning within the window passes
        a single lag that straddles its turn, not every lag. Only since the receiver's last jump (a step between two
        fixes beyond the verdict's gate): a filter walks, it does not jump, so a jump is the output taking the
        measurements again (a fault's end) and the track before it says nothing of a walk now. Each lag's noise is the
        receiver's own clean track's (_walk_noise); jumps are judged on the error model's. NaN without a fix that far
        back."""
        p = self.params
        fixes = [old for old, _ in self._history if old.stamp >= obs.stamp - p.walk_window_s] + [obs]
        steps = [self._step(a, b, ctx) for a, b in zip(fixes, fixes[1:])]
        jumps = [i + 1 for i, (_, _, d2) in enumerate(steps) if d2 > self.gate]
        first = jumps[-1] if jumps else 0
        starts = [i for i in range(first, len(fixes) - 1) if fixes[i].stamp <= obs.stamp - 0.5 * p.window_s]
        if not starts or fixes[starts[0]].stamp > obs.stamp - 0.5 * p.walk_window_s:
            return math.nan
        worst, noise = math.nan, self._walk_noise(ctx)
        for i in starts:
            moved = sum((steps[k][0] for k in range(i, len(steps))), np.zeros(2))
            cov = noise(fixes[i], obs) + sum((steps[k][1] for k in range(i, len(steps))), np.zeros((2, 2)))
            d2 = mahalanobis2(obs.xy - fixes[i].xy - moved, cov)
            worst = d2 if math.isnan(worst) or d2 > worst else worst  # a lag the motion does not cover (NaN) masks none
        return worst

    def _walk_noise(self, ctx: FixContext) -> Callable[[FixObservation, FixObservation], np.ndarray]:
        """The noise of the receiver's displacement between two fixes for the walk test: its own clean track's, learned
        (fusion.monitors.track_noise), once learned and with walk_noise_learned; else the host's error model's. Chosen
        once per fix, so the learned spread is taken once for all its lags."""
        sigma = self._track_noise.sigma_m if self.params.walk_noise_learned else None
        if sigma is None:
            return lambda a, b: self._gps_difference(a, b, ctx)
        return lambda a, b: self._track_noise.noise_of(sigma, a, b)

    def _step(self, a: FixObservation, b: FixObservation, ctx: FixContext) -> tuple[np.ndarray, np.ndarray, float]:
        """The antenna's motion from fix a to fix b by the receiver's own velocity over ground (the mean of the two, its
        error taken as one over the step), or by the odometry where either gives none; its 2x2 covariance; and the
        Mahalanobis distance squared of the receiver's step against it (NaN when neither knows the motion)."""
        va, vb = a.ground_velocity, b.ground_velocity
        dt = b.stamp - a.stamp
        if va is not None and vb is not None:
            moved, cov = 0.5 * (va + vb) * dt, np.eye(2) * (self.params.doppler_sigma_mps * dt) ** 2
        else:
            odometry = self._moved(a.stamp, b.stamp, ctx)
            if odometry is None:
                return np.full(2, math.nan), np.full((2, 2), math.nan), math.nan
            moved, cov = odometry
        return moved, cov, mahalanobis2(b.xy - a.xy - moved, cov + self._gps_difference(a, b, ctx))

    def _reference_at(self, obs: FixObservation, ctx: FixContext) -> tuple[float, np.ndarray, np.ndarray] | None:
        """The reference antenna track carried by the odometry to this fix (None without one)."""
        if self._ref is None or obs.stamp - self._ref_trusted_at > self.params.reference_max_age_s:
            return None
        stamp, xy, cov = self._ref
        moved = self._moved(stamp, obs.stamp, ctx, since=self._ref_trusted_at)
        if moved is None:  # odometry does not cover the step: unknown motion up to max_speed_mps
            spread = (self.params.max_speed_mps * (obs.stamp - stamp)) ** 2
            return obs.stamp, xy, cov + np.eye(2) * spread
        return obs.stamp, xy + moved[0], cov + moved[1]

    def _window_reference(self, stamp: float, verdicts: tuple[str, ...] = ("trusted", "own", "refused")) -> FixObservation | None:
        """The kept fix nearest to `window_s` before stamp (within half to twice that) among those with one of these
        verdicts (trusted, own: refused on its own evidence, refused), or None."""
        target, best = stamp - self.params.window_s, None
        for old, verdict in self._history:
            if verdict not in verdicts:
                continue
            in_window = stamp - 2.0 * self.params.window_s <= old.stamp <= stamp - 0.5 * self.params.window_s
            if in_window and (best is None or abs(old.stamp - target) < abs(best.stamp - target)):
                best = old
        return best

    def _agrees(self, window_d2: float, ref_d2: float) -> bool:
        """The guard's test: the window distance within its gate (NaN fails) and the reference's too (NaN: none, passes)."""
        return window_d2 <= self.guard_gate and not ref_d2 > self.guard_gate

    def check(self, obs: FixObservation, ctx: FixContext) -> Verdict:
        if self._last_measured is None:  # start-up: guarded when the host holds a position of its own (a given pose)
            gap = self.params.startup_guard or ctx.own_start
        else:
            gap = obs.stamp - self._last_measured >= self.params.gap_s
        # window test against a trusted fix (for the verdict) and against any fix (for the guard)
        trusted_ref = None if gap else self._window_reference(obs.stamp, ("trusted", "own"))
        any_ref = None if gap else self._window_reference(obs.stamp)
        guard_d2 = math.nan if any_ref is None else self._distance(any_ref, obs, ctx)
        # no anchor in the window: the receiver's own track must move with the odometry
        window_d2 = guard_d2 if trusted_ref is None else self._distance(trusted_ref, obs, ctx)
        ref = self._reference_at(obs, ctx)
        ref_d2 = math.nan
        if ref is not None:
            r = obs.xy - ref[1]
            ref_d2 = mahalanobis2(r, ref[2] + obs.cov)
        weight = 1.0
        if ctx.correlation_s > 0 and self._last_measured is not None:
            weight = min(1.0, max(obs.stamp - self._last_measured, 1e-3) / ctx.correlation_s)
        steady = guard_d2 <= self.guard_gate  # moves with the odometry since the fix a window earlier (NaN: unknown, not steady)
        # the guard's evidence is the receiver's own track over a window (a walk-back moves it against the odometry), from
        # half a window after the gap on: until then a fix is none either way (None), whatever the reference says (carried
        # over the outage, it is as uncertain as the dead reckoning and passes a walk-back's first metres)
        evidence = None if math.isnan(guard_d2) else self._agrees(guard_d2, ref_d2)
        tests = [d for d in (window_d2, ref_d2) if not math.isnan(d)]
        statistic = max(tests) if tests else math.nan
        passes = 0 if gap else self._guard_passes
        guard_from = obs.stamp if gap else self._guard_start  # None: no guard running
        in_guard = guard_from is not None and (obs.stamp - guard_from < self.params.guard_s or passes < self.params.guard_n)
        # after a long refused stretch the host has dead-reckoned as through a blackout: until a fix passes, its track over
        # the window must also be steady, against a trusted fix there or else any (the window's anchors then are fixes
        # refused on C/N0 during the fault, which carry it), and the reference within the guard's gate
        refused_for = 0.0 if gap or self._refused_since is None else obs.stamp - self._refused_since
        stretch = refused_for >= self.params.refused_s
        failed, track_d2, walk_d2 = bool(tests) and statistic > self.gate, math.nan, math.nan
        if stretch and not failed:
            before = self._window_reference(obs.stamp, ("trusted",))
            track_d2 = guard_d2 if before is None else self._distance(before, obs, ctx)
            # and moved as its own Doppler says since every fix of the last walk window: an overshooting walk-back
            # stands still against the vessel at its turn for about a window
            walk_d2 = self._walk(obs, ctx)
        held = stretch and not failed and not (self._agrees(track_d2, ref_d2) and not walk_d2 > self.guard_gate)
        self._pending = _Pending(gap, ref, evidence, weight, failed or held)
        if failed:
            which = "window" if window_d2 == statistic else "reference"
            why = f"{which} displacement test {statistic:.1f} > gate {self.gate:.1f}"
            return Verdict(False, statistic, why, rule=f"consistency.{which}", steady=steady)
        if held:
            if not track_d2 <= self.guard_gate:  # NaN: no track to judge, held
                which, d2 = "window", track_d2
            else:
                which, d2 = ("walk", walk_d2) if walk_d2 > self.guard_gate else ("reference", ref_d2)
            why = f"{which} displacement test {d2:.1f} > gate {self.guard_gate:.1f} after {refused_for:.1f} s refused"
            return Verdict(False, statistic, why, rule=f"consistency.{which}", steady=steady)
        if in_guard:
            why = f"re-acquisition guard ({passes}/{self.params.guard_n} consistent)"
            return Verdict(False, statistic, why, rule="consistency.guard", steady=steady)
        if not tests:
            return Verdict(True, statistic, "unchecked: no odometry or reference to compare", steady=steady)
        return Verdict(True, statistic, "displacement consistent", steady=steady)

    def commit(self, obs: FixObservation, verdict: Verdict) -> None:
        gap, ref, evidence, weight, failed = self._pending
        if gap:
            self._guard_start, self._guard_passes = obs.stamp, 0
            self._history.clear()
        if self._guard_start is not None:
            if evidence is not None:
                self._guard_passes = self._guard_passes + 1 if evidence else 0
            if obs.stamp - self._guard_start >= self.params.guard_s and self._guard_passes >= self.params.guard_n:
                self._guard_start = None
        self._last_measured = obs.stamp
        self._history.append((obs, "trusted" if verdict.trusted else "own" if verdict.on_its_own else "refused"))
        if verdict.trusted:  # the receiver's clean track, for the walk test's noise
            trusted = []
            for old, label in reversed(self._history):
                if label != "trusted":
                    break
                trusted.append(old)
            self._track_noise.learn(trusted[::-1])
        while self._history and self._history[0][0].stamp < obs.stamp - max(2.0 * self.params.window_s, self.params.walk_window_s):
            self._history.popleft()
        # the refused stretch: fixes that failed this monitor's tests, back to back since the first
        self._refused_since = (obs.stamp if self._refused_since is None else self._refused_since) if failed and not gap else None
        self._ref = ref
        # a fix refused only on its own evidence (a weak satellite: C/N0 says nothing of the position, and this
        # monitor's own tests passed, or the verdict would not be on its own evidence) updates the reference too: without
        # it a receiver whose every fix looked suspect, as open water's tree-lined banks make them, had no reference
        # (gps_jump), and one carried 20 s beside the quickstart's quays outgrew the ramp it had to catch
        if verdict.trusted or verdict.on_its_own:
            if self._ref is None:
                self._ref = (obs.stamp, obs.xy.copy(), obs.cov.copy())
            else:
                stamp, xy, cov = self._ref
                gain = cov @ np.linalg.pinv(cov + obs.cov / weight)
                self._ref = (stamp, xy + gain @ (obs.xy - xy), (np.eye(2) - gain) @ cov)
            self._ref_trusted_at = obs.stamp
