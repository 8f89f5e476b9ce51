"""The simulated chamber of a world on loopback in the bench's dialect, with the real driver connected to it
(as :mod:`drivers.sim.loopback` does for the table and the unit)."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from drivers.chamber.config import ChamberConfig, ChamberLink
from drivers.chamber.connect import open_chamber
from drivers.chamber.watlow import WatlowF4Settings, WatlowF4TSettings
from drivers.connect import Connection
from drivers.sim.chamber_servers import EspecServer, SimservServer, WatlowServer
from drivers.sim.world import SimulatedWorld


def serve_chamber(world: SimulatedWorld, cfg: ChamberConfig) -> tuple[Any, Connection[Any]]:
    """Start the dialect's server on ``world`` and connect the real driver to it over TCP; returns (server,
    connection). Close the connection, then the server."""
    framing = cfg.link.framing or "tcp"
    if cfg.dialect == "watlow_f4":
        opts = cfg.options or WatlowF4Settings()
        server: Any = WatlowServer(world, "f4", framing, address=cfg.address, run_event=opts.run_event)
    elif cfg.dialect == "watlow_f4t":
        opts = cfg.options or WatlowF4TSettings()
        server = WatlowServer(world, "f4t", framing, address=cfg.address, word_order=opts.word_order)
    elif cfg.dialect == "espec":
        server = EspecServer(world)
    else:
        server = SimservServer(world)
    link = ChamberLink("tcp", "127.0.0.1", server.port, framing=framing, send_delay=0.0)
    try:
        conn = open_chamber(replace(cfg, link=link))
    except BaseException:
        server.close()
        raise
    return server, conn
