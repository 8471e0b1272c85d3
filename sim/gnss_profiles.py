"""Receiver profiles: real receiver classes as the defaults of the GNSS parameters (`[gnss] profile = "..."`).

A profile fills in the fields of sim.gnss.GnssConfig that the user did not write; any field written in the same
[gnss] table (or nested table) wins. Each profile names the receiver class it stands for and the datasheet
figures it reproduces in open sky (tests/test_gnss_profiles.py measures them; benchmarks/gnss.py prints them):

- `sbas` (the default, the field study's "uncertainty restricted to less than a meter" in open river): a marine L1
  receiver with carrier-smoothed code and SBAS (WAAS) corrections, as a Hemisphere V102 GPS compass ("L1, C/A code
  with carrier phase smoothing"; horizontal < 1.0 m 95% with differential/SBAS corrections, < 2.5 m 95% autonomous:
  V102 user guide, appendix B, table B-1). Open-sky figure: horizontal 95% 0.9 m (NovAtel SMART2 smart antenna,
  SBAS: docs.novatel.com/OEM7 SMART2 performance specifications); CEP50 = 95% / 2.079 for a circular normal error.
  SBAS broadcasts satellite clock/orbit corrections and an ionospheric grid, which remove most of the slowly
  varying range error; carrier smoothing (a Hatch filter) removes most of the white code noise.
- `sbas_gps`: the same receiver class tracking GPS alone, as the Hemisphere V102 does (user guide: "GPS L1, C/A code"),
  its carrier smoothing restarting when a satellite's lock is lost (noise.restart_white_zenith_m: the raw code's 0.6 m)
  and as a receiver of the field study's era (about 2016) did: Galileo's initial services began on 15 December 2016
  (European Commission) and BeiDou's global service in 2020 (BDS-3, CSNO), so a 2016 marine L1 receiver saw GPS
  (GLONASS at most). Its datasheet figures are sbas's, which are GPS figures. Only `riverbench study --setup field`
  selects it (the field study's receiver); the library keeps sbas with four systems.
- `consumer`: a single-frequency GPS module without corrections, u-blox NEO-M8N (data sheet UBX-15031086:
  horizontal 2.5 m CEP, GPS): the bench's historical receiver model (the fields' own defaults).
- `rtk`: a multi-band RTK receiver with a base station's RTCM 3 corrections, u-blox ZED-F9P (data sheet
  UBX-17051259: 0.01 m + 1 ppm CEP horizontal with an RTK fix, convergence < 10 s); see sim.rtk.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

ProfileName = Literal["sbas", "sbas_gps", "consumer", "rtk"]
DEFAULT_PROFILE: ProfileName = "sbas"

R95_PER_CEP50 = math.sqrt(math.log(20.0) / math.log(2.0))
"""95% radius / CEP50 of a circular normal error (2.079)."""


class Corrections(BaseModel):
    """Differential corrections the receiver applies, and how GGA reports them (quality, age, station id)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    kind: Literal["none", "sbas", "rtk"] = Field(
        "none",
        description="'none': autonomous fixes (GGA quality 1); 'sbas': SBAS/DGPS-corrected code fixes (quality 2); 'rtk': "
        "carrier-phase RTK (quality 4 fixed, 5 float; sim.rtk). NMEA 0183 v2.3 GGA quality field.",
    )
    interval_s: float = Field(
        1.0,
        gt=0.0,
        le=60.0,
        description="Period of the correction messages, s: GGA field 13 (age of differential data) cycles from latency_s to "
        "latency_s + interval_s (RTCM 3 observations from a base: 1 Hz, u-blox ZED-F9P integration manual UBX-18010802; "
        "SBAS fast corrections: every 6 s, RTCA DO-229).",
    )
    latency_s: float = Field(0.0, ge=0.0, le=60.0, description="Delay from a correction's epoch to its use (radio link or NTRIP), s.")
    station_id: int = Field(
        0,
        ge=0,
        le=1023,
        description="GGA field 14, differential reference station id (0000-1023, NMEA 0183): the base's RTCM 1005 id for "
        "RTK (u-blox default 0), the broadcasting geostationary satellite's PRN for SBAS (WAAS: 131, 133, 135).",
    )

    def age_s(self, t: float) -> float:
        """Age of the corrections in use at scenario time t (s), as GGA field 13 reports it."""
        return self.latency_s + t % self.interval_s


@dataclass(frozen=True)
class Profile:
    """A receiver class: the datasheet figures it reproduces in open sky and the field defaults that give them, each
    with its source or physical reason (`why`, by dotted field name)."""

    receiver: str
    cep50_m: float
    p95_m: float
    figures: str
    defaults: dict[str, Any]
    why: dict[str, str]


_SBAS_WHY = {
    "noise.white_zenith_m": "carrier-smoothed code (Hatch filter; V102: 'C/A code with carrier phase smoothing') leaves "
    "0.15 m of the 0.6 m white code noise at zenith",
    "noise.correlated_zenith_m": "SBAS clock/orbit corrections and ionospheric grid leave a slowly varying residual of "
    "0.24 m at zenith (1.5 m without them); the value whose open-sky horizontal 95% is the datasheet's 0.9 m",
    "filter.fix_sigma_m": "the filter's allowance for slow errors, scaled with them from the consumer's (2.5 m for 1.5 m)",
    "corrections": "SBAS: GGA quality 2, fast corrections every 6 s (RTCA DO-229), station = WAAS GEO PRN 133",
}
PROFILES: dict[str, Profile] = {
    "consumer": Profile(
        receiver="u-blox NEO-M8N, GPS L1 C/A, no corrections",
        cep50_m=2.5,
        p95_m=2.5 * R95_PER_CEP50,
        figures="NEO-M8N data sheet UBX-15031086: horizontal 2.5 m CEP (GPS); 95% = 2.079 CEP (circular normal)",
        defaults={},
        why={"*": "the fields' own defaults (the bench's historical consumer receiver, CEP50 2.5 m)"},
    ),
    "sbas": Profile(
        receiver="marine L1 receiver with SBAS (WAAS) and carrier-smoothed code, Hemisphere V102 class",
        cep50_m=0.9 / R95_PER_CEP50,
        p95_m=0.9,
        figures="NovAtel SMART2 SBAS horizontal 95% 0.9 m (docs.novatel.com OEM7, SMART2 performance specifications); "
        "Hemisphere V102 user guide table B-1: < 1.0 m 95% with corrections; CEP50 = 95% / 2.079 (circular normal)",
        defaults={
            "noise": {"white_zenith_m": 0.15, "correlated_zenith_m": 0.24},
            "filter": {"fix_sigma_m": 0.4},
            "corrections": {"kind": "sbas", "interval_s": 6.0, "station_id": 133},
        },
        why=_SBAS_WHY,
    ),
    "sbas_gps": Profile(
        receiver="marine L1 receiver with SBAS (WAAS) and carrier-smoothed code tracking GPS alone, Hemisphere V102 "
        "(GPS L1 C/A), the field study's era (about 2016)",
        cep50_m=0.9 / R95_PER_CEP50,
        p95_m=0.9,
        figures="as sbas (the V102's and the SMART2's figures are GPS figures)",
        defaults={
            "noise": {"white_zenith_m": 0.15, "correlated_zenith_m": 0.24, "restart_white_zenith_m": 0.6},
            "filter": {"fix_sigma_m": 0.4},
            "corrections": {"kind": "sbas", "interval_s": 6.0, "station_id": 133},
            "constellations": ("GPS",),
        },
        why={
            **_SBAS_WHY,
            "noise.restart_white_zenith_m": "carrier smoothing restarts when a satellite's lock is lost (Ashtech G12 SMI: "
            "'After reacquisition, smoothing is reset'; NovAtel CSMOOTH; Septentrio setSmoothingInterval; Hemisphere, the "
            "V102's maker, smooths over 15 min by default, $JSMOOTH): a range reacquired after a bridge starts with the raw "
            "code's 0.6 m white noise (the consumer's) and is averaged down to the smoothed 0.15 m as its window grows. "
            "The physics of every carrier-smoothing receiver; the library's sbas keeps it off until its baseline is "
            "refreshed (issue 42)",
            "constellations": "GPS alone: the Hemisphere V102 tracks GPS L1 C/A (user guide, appendix B); in 2016 Galileo's "
            "initial services had not begun (15 December 2016, European Commission) nor BeiDou's global service (2020)",
        },
    ),
    "rtk": Profile(
        receiver="u-blox ZED-F9P multi-band RTK rover with a base station's RTCM 3 corrections",
        cep50_m=0.01 + 1e-6 * 5000.0,
        p95_m=(0.01 + 1e-6 * 5000.0) * R95_PER_CEP50,
        figures="ZED-F9P data sheet UBX-17051259: RTK 0.01 m + 1 ppm CEP horizontal (5 km baseline: 0.015 m), "
        "convergence < 10 s; 95% = 2.079 CEP (circular normal)",
        defaults={
            "noise": {"white_zenith_m": 0.15, "correlated_zenith_m": 0.24},
            "filter": {"fix_sigma_m": 0.4},
            "corrections": {"kind": "rtk", "interval_s": 1.0, "latency_s": 0.2, "station_id": 0},
        },
        why={
            "noise": "code differentially corrected by the base 5 km away: residuals as SBAS's (float start, no-fix epochs)",
            "filter.fix_sigma_m": "as sbas",
            "corrections": "RTCM 3 at 1 Hz from the base (ZED-F9P integration manual UBX-18010802), 0.2 s radio latency, "
            "reference station id 0 (u-blox default)",
            "rtk": "sim.rtk.RtkConfig: ZED-F9P data sheet figures, 5 km baseline",
        },
    ),
}
"""The receiver profiles by name; a profile's defaults fill the sim.gnss.GnssConfig fields the user did not write."""


def _plain(value: Any) -> Any:
    """A nested model as the dict of the fields its author set (so that a profile still fills the others)."""
    return value.model_dump(exclude_unset=True) if isinstance(value, BaseModel) else value


def with_profile(data: dict[str, Any]) -> dict[str, Any]:
    """The [gnss] table `data` with its profile's defaults filled in where it has no value of its own (an unknown
    profile is left for the field's validation to name)."""
    name = data.get("profile", DEFAULT_PROFILE)
    profile = PROFILES.get(name) if isinstance(name, str) else None
    return _merged(profile.defaults if profile else {}, data)


def _merged(defaults: dict[str, Any], data: dict[str, Any]) -> dict[str, Any]:
    out = dict(data)
    for key, default in defaults.items():
        value = _plain(out.get(key))
        if key not in out:
            out[key] = default
        elif isinstance(default, dict) and isinstance(value, dict):
            out[key] = _merged(default, value)
    return out
