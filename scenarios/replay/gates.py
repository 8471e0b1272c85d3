"""Which check refused a replay's scans, and the --set key that changes it.

A real recording can fall outside the defaults a simulated river was tuned on (a car at 30 kn, a 20 Hz VLP-16's
sparser rings): when one check refuses most of a matcher's scans (more than MOST of them), the
replay says which, with an example of its reason and the key to change. The check is the matcher parameter its
reason names (every matcher's refusals do: "implausible motion: 14.2 m/s > max_speed_mps 10.0",
"too few points: 312 < gate_min_points 500").
"""

from __future__ import annotations

import re
from collections import Counter

from scenarios.spec.scenario import Scenario

MOST = 0.5


class RefusalTally:
    """Counts, per matcher, its refused scans by the parameter their reason names; call it with (stamp, results) after each scan."""

    def __init__(self, scenario: Scenario) -> None:
        self._keys = {m.id: sorted(m.params, key=len, reverse=True) for m in scenario.matchers}
        self._scans: Counter[str] = Counter()
        self._refused: dict[str, Counter[str]] = {m: Counter() for m in self._keys}
        self._example: dict[tuple[str, str], str] = {}

    def __call__(self, stamp: float, results: dict) -> None:
        for mid, result in results.items():
            self._scans[mid] += 1
            reason = str(result.info.get("reason", "")) if not result.ok else ""
            key = next((k for k in self._keys.get(mid, []) if re.search(rf"\b{re.escape(k)}\b", reason)), None)
            if key is not None:
                self._refused[mid][key] += 1
                self._example.setdefault((mid, key), reason)

    def warnings(self) -> list[str]:
        """One line per check that refused most of a matcher's scans."""
        out = []
        for mid, refused in self._refused.items():
            scans = self._scans[mid]
            for key, n in refused.most_common():
                if n > MOST * scans:
                    out.append(
                        f"{mid}: {key} refused {n} of {scans} scans (e.g. {self._example[(mid, key)]!r}); "
                        f"change it with --set matchers.{mid}.params.{key}=VALUE"
                    )
        return out
