"""The bench file's ``chamber:`` section → :class:`~drivers.chamber.connect.ChamberConfig` (SI inside; °C and s
in the file). Every open point of a dialect is a key of ``options:`` with the documented default
(docs/protocols/chambers.md); an unknown key or a bad value is one line naming the place and what is allowed.

Example::

    chamber:
      dialect: espec                 # watlow_f4 | watlow_f4t | espec | simserv
      driver: real                   # real, or sim: the dialect served on loopback by the simulated world
      link: {kind: tcp, address: 192.168.1.20, port: 10001}
      setpoint_min_c: -40
      setpoint_max_c: 85
      safe_setpoint_c: 25
      warm_up_below_c: 10            # optional: warm up before stopping below it (dew-point margin)
      options: {setpoint_form: spaced}
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from analysis.units import celsius_to_kelvin
from core.yaml_source import SourceMap, check_keys, get_int, get_mapping, get_number, get_str
from drivers.chamber.base import ChamberSettings
from drivers.chamber.config import DIALECTS, ChamberConfig, ChamberLink
from drivers.chamber.espec import EspecSettings
from drivers.chamber.simserv import SimservSettings
from drivers.chamber.watlow import WatlowF4Settings, WatlowF4TSettings

KeyPath = tuple[Any, ...]
KEYS = (
    "dialect", "driver", "link", "modbus", "setpoint_min_c", "setpoint_max_c", "safe_setpoint_c",
    "warm_up_below_c", "warm_up_timeout_s", "timeout_s", "options", "name",
)  # fmt: skip


@dataclass(frozen=True)
class ChamberSection:
    """A parsed ``chamber:`` section: the connection config and whether it is the simulated chamber."""

    config: ChamberConfig
    simulated: bool
    line: int | None = None


def _link(d: dict, smap: SourceMap, p: KeyPath, simulated: bool) -> ChamberLink:
    if simulated and not d:
        return ChamberLink("tcp", "127.0.0.1")
    check_keys(d, smap, p, ["kind", "address", "port", "baudrate", "bytesize", "parity", "stopbits"])
    kind = get_str(d, smap, p, "kind", choices=("serial", "tcp", "visa"))
    address = get_str(d, smap, p, "address")
    port = get_int(d, smap, p, "port", 0, 0, 65535) if "port" in d else None
    return ChamberLink(
        kind,  # type: ignore[arg-type]
        address,
        port,
        baudrate=get_int(d, smap, p, "baudrate", 9600, 300, 4_000_000),
        bytesize=get_int(d, smap, p, "bytesize", 8, 5, 8),
        parity=get_str(d, smap, p, "parity", "N", choices=("N", "E", "O")),
        stopbits=get_number(d, smap, p, "stopbits", 1.0, minimum=1.0, maximum=2.0),
    )


def _options(dialect: str, d: dict, smap: SourceMap, p: KeyPath) -> Any:
    if dialect == "watlow_f4":
        check_keys(d, smap, p, ["loop", "decimals", "pv_function", "run_event", "check_units"])
        return WatlowF4Settings(
            loop=get_int(d, smap, p, "loop", 1, 1, 2),
            decimals=get_int(d, smap, p, "decimals", 0, 0, 3) if "decimals" in d else None,
            pv_function=get_int(d, smap, p, "pv_function", 3, 3, 4),
            run_event=get_int(d, smap, p, "run_event", 1, 1, 8) if "run_event" in d else None,
            check_units=_bool(d, smap, p, "check_units", True),
        )
    if dialect == "watlow_f4t":
        check_keys(d, smap, p, ["loop", "word_order"])
        return WatlowF4TSettings(
            loop=get_int(d, smap, p, "loop", 1, 1, 4),
            word_order=get_str(d, smap, p, "word_order", "low_first", choices=("low_first", "high_first")),  # type: ignore[arg-type]
        )
    if dialect == "espec":
        check_keys(d, smap, p, ["address", "setpoint_form", "power_off_on_stop"])
        return EspecSettings(
            address=get_int(d, smap, p, "address", 1, 1, 16) if "address" in d else None,
            setpoint_form=get_str(d, smap, p, "setpoint_form", "spaced", choices=("spaced", "compact")),  # type: ignore[arg-type]
            power_off_on_stop=_bool(d, smap, p, "power_off_on_stop", False),
        )
    check_keys(d, smap, p, ["chamber_index", "leading_separator", "run_pause_s", "temperature_variable", "run_output"])
    return SimservSettings(
        chamber_index=get_int(d, smap, p, "chamber_index", 1, 1, 99),
        leading_separator=_bool(d, smap, p, "leading_separator", False),
        run_pause=get_number(d, smap, p, "run_pause_s", 1.0, minimum=0.0, maximum=60.0),
        temperature_variable=get_int(d, smap, p, "temperature_variable", 1, 1, 99),
        run_output=get_int(d, smap, p, "run_output", 1, 1, 99),
    )


def _bool(d: dict, smap: SourceMap, p: KeyPath, key: str, default: bool) -> bool:
    v = d.get(key, default)
    if not isinstance(v, bool):
        raise smap.error(p + (key,), f"expected true or false, got {v!r}")
    return v


def parse_chamber(data: Any, smap: SourceMap, path: KeyPath = ("chamber",)) -> ChamberSection:
    """Parse the ``chamber:`` section (see the module docstring)."""
    d = get_mapping(data, smap, path)
    check_keys(d, smap, path, KEYS)
    dialect = get_str(d, smap, path, "dialect", choices=DIALECTS)
    simulated = get_str(d, smap, path, "driver", "real", choices=("real", "sim")) == "sim"
    link = _link(get_mapping(d.get("link") or {}, smap, path + ("link",)), smap, path + ("link",), simulated)
    if link.kind == "visa" and dialect != "espec":
        raise smap.error(path + ("link", "kind"), f"visa is for the espec dialect only; {dialect} uses serial or tcp")
    mb = get_mapping(d.get("modbus") or {}, smap, path + ("modbus",))
    mp = path + ("modbus",)
    check_keys(mb, smap, mp, ["address", "framing", "send_delay_s"])
    if mb and not dialect.startswith("watlow"):
        raise smap.error(mp, f"modbus: is for the watlow dialects only, not {dialect}")
    framing = get_str(mb, smap, mp, "framing", None, choices=("rtu", "tcp"))
    delay = get_number(mb, smap, mp, "send_delay_s", None, minimum=0.0, maximum=1.0)
    link = ChamberLink(**{**link.__dict__, "framing": framing, "send_delay": delay})
    lo = get_number(d, smap, path, "setpoint_min_c", -40.0, minimum=-100.0, maximum=300.0)
    hi = get_number(d, smap, path, "setpoint_max_c", 150.0, minimum=-100.0, maximum=300.0)
    if not lo < hi:
        raise smap.error(path + ("setpoint_max_c",), f"must be above setpoint_min_c ({lo:g} °C)")
    safe = get_number(d, smap, path, "safe_setpoint_c", 25.0, minimum=lo, maximum=hi)
    warm = get_number(d, smap, path, "warm_up_below_c", None, minimum=lo, maximum=hi)
    settings = ChamberSettings(
        setpoint_min=celsius_to_kelvin(lo),
        setpoint_max=celsius_to_kelvin(hi),
        safe_setpoint=celsius_to_kelvin(safe),
        warm_up_below=None if warm is None else celsius_to_kelvin(warm),
        warm_up_timeout=get_number(d, smap, path, "warm_up_timeout_s", 3600.0, minimum=0.0, maximum=86400.0),
        timeout=get_number(d, smap, path, "timeout_s", 3.0, minimum=0.05, maximum=60.0, exclusive_minimum=False),
    )
    opts = _options(dialect, get_mapping(d.get("options") or {}, smap, path + ("options",)), smap, path + ("options",))
    if simulated and dialect == "simserv":
        opts = SimservSettings(**{**opts.__dict__, "run_pause": 0.0}) if "options" not in d else opts
    cfg = ChamberConfig(
        dialect,  # type: ignore[arg-type]
        link,
        settings,
        opts,
        address=get_int(mb, smap, mp, "address", 1, 1, 247),
        name=get_str(d, smap, path, "name", "chamber"),
    )
    return ChamberSection(cfg, simulated, smap.line(path))
