"""The ``consistid`` command: subcommands (:mod:`.commands`), the TOML schema (:mod:`.config`)
and the simulated-gap demo (:mod:`.residual_demo`)."""

from .commands import main

__all__ = ["main"]
