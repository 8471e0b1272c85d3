"""A matcher or estimator of `kind = "command"`: an executable run on the run's recording (any language, any stack), its
trajectory read back under the contract `riverbench score` takes (scenarios.score.external.Contract).

Written in a scenario's [[matchers]] or [[estimators]] like a built-in, validated here at load: a placeholder of
`command` must be one the bench fills ({recording}, {out}, {workdir}) or a key of `params`, so a sweep that varies
`matchers.<id>.params.<key>` reaches the command (also as the environment variable RIVERBENCH_PARAM_<KEY>).
"""

from __future__ import annotations

import re
import shlex
import string
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from scenarios.score.external import Anchor, Clock, Contract, Format, Frame

KIND = "command"
Recording = Literal["rosbag2", "mcap", "kitti", "pcap", "nmea"]
FILLED = ("recording", "out", "workdir")
"""Placeholders the bench fills: the recording's path, the command's output folder and its working folder."""
PARAM_KEY = r"^[A-Za-z_][A-Za-z0-9_]*$"


class CommandSpec(BaseModel):
    """An external component: the command the bench runs on a recording of the scenario and how its output is read."""

    model_config = ConfigDict(extra="forbid")

    id: str = Field(..., pattern=r"^[A-Za-z_][A-Za-z0-9_]*$", description="name of this instance in metrics and files")
    kind: Literal["command"] = Field(..., description="'command': run an executable on the run's recording")
    command: str = Field(
        ...,
        min_length=1,
        description="the command line (split as a POSIX shell would, run without a shell); placeholders {recording}, {out}, "
        "{workdir} and {<key>} of params are filled in, e.g. 'kiss_icp_pipeline {recording} --max_range {max_range}'",
    )
    recording: Recording = Field(
        "rosbag2", description="what it reads: rosbag2 or mcap (bag directory), kitti (KITTI odometry directory), pcap (file), nmea (NMEA 0183 log)"
    )
    output: str = Field(
        ..., min_length=1, description="glob, relative to its working folder, of the one trajectory file it writes, e.g. 'results/**/*_poses_tum.txt'"
    )
    format: Format = Field("tum", description="the output's format (as `riverbench score --format`)")
    times: str | None = Field(None, description="kitti only: glob, relative to its working folder, of the file of one stamp per pose line")
    frame: Frame = Field("base_link", description="whose poses they are (as `riverbench score --frame`)")
    clock: Clock = Field("unix", description="the stamps' clock (as `riverbench score --clock`)")
    anchor: Anchor = Field("map", description="how the poses are laid onto the world (as `riverbench score --anchor`)")
    min_coverage: float = Field(
        0.5,
        ge=0.0,
        le=1.0,
        description="the share of the run's scans that must get a pose (each takes the one stamped nearest it within a quarter "
        "revolution); below it the component fails: a stack that drops most frames is not scored as if it kept up",
    )
    timeout_s: float = Field(600.0, gt=0, description="the command is ended (SIGTERM, then SIGKILL, its process group) after this long, s")
    params: dict[str, str | int | float | bool] = Field(
        default_factory=dict, description="values for the command's {<key>} placeholders, also exported as RIVERBENCH_PARAM_<KEY>"
    )

    @field_validator("params")
    @classmethod
    def _keys(cls, params: dict) -> dict:
        for key in params:
            if not re.match(PARAM_KEY, key) or key in FILLED:
                raise ValueError(f"params key {key!r}: a letter or _, then letters, digits or _; not one of {', '.join(FILLED)}")
        return params

    @model_validator(mode="after")
    def _placeholders(self) -> CommandSpec:
        try:
            words = shlex.split(self.command)
        except ValueError as exc:
            raise ValueError(f"command {self.command!r}: {exc}") from None
        if not words:
            raise ValueError("command: empty")
        known = {*FILLED, *self.params}
        for word in words:
            for name in placeholders(word, self.command):
                if name not in known:
                    raise ValueError(f"command: unknown placeholder {{{name}}}; use {', '.join('{' + k + '}' for k in sorted(known))}")
        if (self.format == "kitti") != (self.times is not None):
            raise ValueError("times: give it with format = 'kitti' (KITTI poses carry no stamps), and only then")
        return self

    def argv(self, values: dict[str, str]) -> list[str]:
        """The command's words with every placeholder filled in (`values`: recording, out, workdir) and the params'."""
        fill = {**{k: str(v) for k, v in self.params.items()}, **values}
        return [word.format(**fill) for word in shlex.split(self.command)]

    def environment(self, values: dict[str, str]) -> dict[str, str]:
        """The variables the command gets besides the bench's environment: RIVERBENCH_PARAM_<KEY> and RIVERBENCH_<FILLED>."""
        params = {f"RIVERBENCH_PARAM_{k.upper()}": str(v) for k, v in self.params.items()}
        return params | {f"RIVERBENCH_{k.upper()}": v for k, v in values.items()}

    def contract(self, times: str | None) -> Contract:
        """The contract the output is read under (`times`: the path the `times` glob matched)."""
        return Contract(format=self.format, times=times, frame=self.frame, clock=self.clock, anchor=self.anchor)


def placeholders(word: str, command: str) -> list[str]:
    """The {names} in one word of the command; a malformed brace is one line naming the command."""
    try:
        return [name for _, name, _, _ in string.Formatter().parse(word) if name is not None]
    except ValueError as exc:
        raise ValueError(f"command {command!r}: {exc} (write a literal brace as {{{{ or }}}})") from None
