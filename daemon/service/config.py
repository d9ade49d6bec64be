"""The daemon's configuration: a TOML file, overridden by ``GUIDEBELT_…`` environment variables.

Nested keys use ``__`` in the environment, e.g. ``GUIDEBELT_ZENOH__LISTEN='["tcp/0.0.0.0:7447"]'``
or ``GUIDEBELT_BACKEND=cpu``. Unknown keys are an error, so a typo never goes unnoticed.
An example with every key is ``systemd/guidebelt.toml``.
"""

from __future__ import annotations

import os
import socket
from pathlib import Path
from typing import Annotated, Literal

from pydantic import Field, field_validator
from pydantic_settings import (
    BaseSettings,
    PydanticBaseSettingsSource,
    SettingsConfigDict,
    TomlConfigSettingsSource,
)

from daemon.navigation import NavigatorSettings
from daemon.navigation.controls import BatteryPolicy
from daemon.planning.registry import PLANNERS
from protocol.settings import ZenohSettings

__all__ = ["DaemonConfig", "ZenohSettings", "load_config"]

DEFAULT_CONFIG_FILE = Path("/etc/guidebelt/guidebelt.toml")
DEFAULT_STATE_DIR = Path("/var/lib/guidebelt")
"""The unit's ``StateDirectory=guidebelt``."""


def _default_state_dir() -> Path:
    # systemd names the StateDirectory in $STATE_DIRECTORY (several: colon-separated).
    named = os.environ.get("STATE_DIRECTORY", "").split(":")[0]
    return Path(named) if named else DEFAULT_STATE_DIR


Metres = Annotated[float, Field(ge=-100_000, le=100_000, allow_inf_nan=False)]
LandmarkName = Annotated[str, Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_ -]+$")]


class DaemonConfig(BaseSettings):
    # No value can be infinite or NaN: every number below reaches a conversion or a sleep.
    model_config = SettingsConfigDict(
        env_prefix="GUIDEBELT_", env_nested_delimiter="__", extra="forbid", allow_inf_nan=False
    )

    daemon_id: str = Field(default_factory=socket.gethostname, min_length=1, max_length=64)
    zenoh: ZenohSettings = Field(default_factory=ZenohSettings)
    planner: str = Field(default="eds", description="a planner of the registry: eds, dss, …")
    backend: Literal["auto", "cpu", "cuda", "reference"] = "auto"
    variant: Literal["fast", "paper"] = "fast"
    cell_m: float = Field(default=0.10, gt=0, le=1.0)
    user_radius_m: float = Field(default=0.3, ge=0, le=2.0, description="obstacles grow by this")
    lang: Literal["en", "es"] = "en"
    voice: Literal["companion", "sole"] = Field(
        default="companion",
        description="companion: the voice speaks beside the belt; sole: it guides alone",
    )
    wording: Literal["clock", "sides"] = Field(
        default="clock", description="turn to 2 o'clock, or turn slightly right"
    )
    units: Literal["metric", "imperial"] = Field(default="metric", description="metres or feet")
    reassure_s: float = Field(
        default=15.0, ge=0, le=600, description="the way said again on a long leg (0: never)"
    )
    stale_pose_s: float = Field(default=1.0, gt=0, le=60, description="older poses are refused")
    stop_m: float = Field(
        default=0.6, gt=0, le=5, description="an obstacle nearer than this ahead: STOP"
    )
    max_users: int = Field(default=16, ge=1, le=10_000)
    max_map_cells: int = Field(
        default=2048 * 2048, ge=1, le=4096 * 4096, description="the largest map one user may have"
    )
    memory_budget_mb: float = Field(
        default=2048, gt=0, le=1_000_000, description="all users' maps and planners together"
    )
    user_idle_s: float = Field(
        default=600.0, gt=0, le=86_400, description="forget a silent, idle user"
    )
    tick_s: float = Field(default=0.25, gt=0, le=60, description="staleness checks and watchdog")
    guide_hz: float = Field(
        default=10.0,
        ge=1,
        le=100,
        description="a pose alone re-guides a user at most this often; a map change, goal, "
        "refusal or button steps at once",
    )
    step_workers: int = Field(
        default=0, ge=0, le=256, description="users stepped at once; 0: one per CPU core"
    )
    workers: int = Field(
        default=0,
        ge=0,
        le=64,
        description="worker processes the users are shared among, each with its own GIL and "
        "zenoh session (the daemon then routes between them and the clients); 0: every user "
        "in the daemon's own process",
    )
    lag_budget_ms: float = Field(
        default=50.0,
        ge=5,
        le=10_000,
        description="input→belt delay every guided user should stay within; past it the "
        "users admitted last are told 'overloaded' until the daemon keeps up again",
    )
    step_cpu_budget_ms: float = Field(
        default=600.0,
        ge=10,
        le=1_000_000,
        description="CPU ms per second all guided users' steps may take together (their "
        "Python parts share one core; the compiled planners run beside it)",
    )
    snapshot_timeout_s: float = Field(default=1.0, gt=0, le=60)
    landmarks: dict[LandmarkName, tuple[Metres, Metres]] = Field(
        default_factory=dict, max_length=1000, description="named goals: name = [x, y] in metres"
    )
    intensity: int = Field(
        default=100, ge=0, le=100, description="a new user's belt intensity (settings/set)"
    )
    state_dir: Path | None = Field(
        default_factory=_default_state_dir,
        description="goals, maps, sessions and users' settings survive restarts here "
        "(state.db); default $STATE_DIRECTORY or /var/lib/guidebelt; empty: nothing kept",
    )
    settings_dir: Path | None = Field(
        default=None,
        description="no longer used (settings live in state_dir): its <user>.json files are "
        "imported once into the state database",
    )
    persist_map_s: float = Field(
        default=2.0, ge=0.1, le=3600, description="each user's map written at most this often"
    )
    low_battery_v: float = Field(default=3.5, gt=0, le=10, description="the belt warns below this")
    battery_empty_v: float = Field(default=3.3, gt=0, le=10, description="0 % when spoken")
    battery_full_v: float = Field(default=4.2, gt=0, le=10, description="100 % when spoken")
    log_level: Literal["DEBUG", "INFO", "WARNING", "ERROR"] = "INFO"
    log_format: Literal["journal", "json"] = "journal"

    @field_validator("state_dir", mode="before")
    @classmethod
    def _empty_is_none(cls, value: object) -> object:
        return None if value in ("", None) else value

    @field_validator("planner")
    @classmethod
    def _known_planner(cls, name: str) -> str:
        if name not in PLANNERS:
            raise ValueError(f"unknown planner {name!r}; choose one of {', '.join(PLANNERS)}")
        return name

    def navigator_settings(self) -> NavigatorSettings:
        """What each user's navigator takes from the daemon's config."""
        return NavigatorSettings(
            planner=self.planner,
            backend=self.backend,
            variant=self.variant,
            cell_m=self.cell_m,
            user_radius_m=self.user_radius_m,
            lang=self.lang,
            voice=self.voice,
            wording=self.wording,
            units=self.units,
            reassure_s=self.reassure_s,
            stale_pose_s=self.stale_pose_s,
            stop_m=self.stop_m,
            landmarks=dict(self.landmarks),
            battery=BatteryPolicy(
                low_v=self.low_battery_v, empty_v=self.battery_empty_v, full_v=self.battery_full_v
            ),
        )

    @classmethod
    def settings_customise_sources(
        cls,
        settings_cls: type[BaseSettings],
        init_settings: PydanticBaseSettingsSource,
        env_settings: PydanticBaseSettingsSource,
        dotenv_settings: PydanticBaseSettingsSource,
        file_secret_settings: PydanticBaseSettingsSource,
    ) -> tuple[PydanticBaseSettingsSource, ...]:
        # Arguments beat the environment, which beats the file.
        return (init_settings, env_settings, TomlConfigSettingsSource(settings_cls))


def load_config(path: str | Path | None = None, **overrides: object) -> DaemonConfig:
    """The config from ``path`` (or $GUIDEBELT_CONFIG, or /etc/guidebelt/guidebelt.toml if
    present), the environment and ``overrides``. A named file that is missing is an error."""
    if path is None:
        env_path = os.environ.get("GUIDEBELT_CONFIG")
        if env_path:
            path = env_path
        elif DEFAULT_CONFIG_FILE.is_file():
            path = DEFAULT_CONFIG_FILE
    if path is not None and not Path(path).is_file():
        raise FileNotFoundError(f"config file {path} not found")

    class _FromFile(DaemonConfig):
        model_config = SettingsConfigDict(toml_file=path)

    return _FromFile(**overrides)
