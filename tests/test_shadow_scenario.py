"""The 'shadow' monitor in a run: the canal's walls, seen by the simulated HDL-32E, show which used satellites are NLOS.

canal_multipath's stations 220-330 m (the canyon's entry: fixes with and without NLOS satellites, seed 0), the ekf
beside an ekf whose monitor is consistency + shadow. The run feeds the
shadow ekf each scan's points (scenarios.pipeline.feed); its refusals must be the fixes whose used satellites the
simulator's truth marks NLOS, and it must refuse more of those than of the others.
"""

from __future__ import annotations

import csv

import numpy as np
import pytest

import scenarios
from scenarios.spec.library import load


@pytest.mark.slow
def test_the_shadow_monitor_refuses_the_fixes_that_use_nlos_satellites(tmp_path):
    base = load("canal_multipath")
    shadow = base.estimators[[e.id for e in base.estimators].index("ekf")].model_copy(
        update={"id": "ekf_shadow", "monitor_params": {"members": ["consistency", "shadow"]}}
    )
    stretch = base.stretch.model_copy(update={"start_m": 220.0, "end_m": 330.0})
    scenario = base.model_copy(update={"estimators": [*base.estimators, shadow], "stretch": stretch})
    scenarios.run(scenario, tmp_path / "run", workers=1)
    with open(tmp_path / "run" / "gps.csv") as f:
        rows = [r for r in csv.DictReader(f) if r["quality"] not in ("0", "")]
    refused = np.array([r["ekf_shadow.trusted"] in ("False", "0", "false") for r in rows])
    nlos = np.array([int(float(r["nlos_used"] or 0)) > 0 for r in rows])
    off = np.array([float(r["added_err_h"] or "nan") > 5.0 for r in rows])
    print(
        f"fixes {len(rows)}, using NLOS {nlos.sum()}, > 5 m {off.sum()}; refused: of NLOS {refused[nlos].mean():.2f}, "
        f"of direct-only {refused[~nlos].mean():.2f}, of > 5 m {refused[off].mean() if off.any() else float('nan'):.2f}"
    )
    assert nlos.sum() >= 20 and (~nlos).sum() >= 20
    assert refused[nlos].mean() >= 2.0 * refused[~nlos].mean()
    if off.any():
        assert refused[off].mean() >= 0.9
