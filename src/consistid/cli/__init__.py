"""The ``consistid`` command: subcommands (:mod:`.commands`), the TOML schema (:mod:`.config`)
and the simulated-gap demo (:mod:`.residual_demo`).

:func:`main` imports the subcommands (Pinocchio, cvxpy, MuJoCo: seconds) under the same signal
rules as the run itself: Ctrl-C or SIGTERM while they load ends the command with the shell's
130 or 143 and one line, never a traceback of the import machinery (nothing is written yet).
"""

from __future__ import annotations

import sys
from typing import Sequence

from ..filesafety import Terminated, sigterm_interrupts

__all__ = ["main"]


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``consistid`` command (:func:`consistid.cli.commands.main`)."""
    try:
        with sigterm_interrupts():
            from .commands import main as run
    except KeyboardInterrupt as exc:
        name, code = ("SIGTERM", 143) if isinstance(exc, Terminated) else ("SIGINT", 130)
        print(f"consistid: interrupted ({name}) while starting; nothing was written",
              file=sys.stderr, flush=True)
        return code
    return run(argv)
