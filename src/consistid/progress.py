"""Progress feedback for long calls: a ``tqdm`` bar on a terminal, silence in a pipe.

Every long-running function of consistid (multi-start excitation design, diagnosis, Monte Carlo
loops, large files) takes ``progress=``:

``None`` (default)
    a bar on ``stderr`` when ``stderr`` is a terminal (``isatty``), nothing otherwise (logs, CI,
    pipes and notebooks stay clean);
``True`` / ``False``
    always / never a bar;
a callable
    called with one line of text per step instead of a bar (what a GUI or a logger wants).

The ``consistid`` command runs under :func:`silenced` with ``-q``: there ``None`` means no
bar, wherever the call is made. ``tqdm`` is imported only when a bar is drawn.
"""

from __future__ import annotations

import contextlib
import sys
from typing import Any, Callable, Iterator, Union

from .errors import MissingDependencyError, OptionError

#: What ``progress=`` accepts (module docstring).
ProgressArg = Union[bool, None, Callable[[str], None]]


#: Inside :func:`silenced`: ``progress=None`` draws no bar.
_SILENCED = [False]


@contextlib.contextmanager
def silenced(on: bool = True) -> Iterator[None]:
    """Within the block, ``progress=None`` draws no bar (``-q`` of the ``consistid`` command);
    an explicit ``True`` or callable still reports."""
    before = _SILENCED[0]
    _SILENCED[0] = bool(on)
    try:
        yield
    finally:
        _SILENCED[0] = before


def wants_bar(progress: ProgressArg) -> bool:
    """Whether ``progress`` asks for a drawn bar (``None``: when stderr is a terminal, outside
    :func:`silenced`)."""
    if progress is None:
        if _SILENCED[0]:
            return False
        stream = sys.stderr
        return bool(stream is not None and hasattr(stream, "isatty") and stream.isatty())
    return progress is True


class Progress:
    """A progress reporter over ``total`` steps (``None``: unknown), used as a context manager.

    ``step(text)`` advances by one and shows ``text`` (the bar's postfix, or the line passed to
    a callable); ``close()`` ends the bar.
    """

    def __init__(self, progress: ProgressArg, total: int | None, desc: str,
                 unit: str = "step") -> None:
        if not (progress is None or isinstance(progress, bool) or callable(progress)):
            raise OptionError(f"progress must be None (a bar on a terminal), True, False or a "
                              f"callable taking a line of text, got {progress!r}")
        self.callback = progress if callable(progress) and not isinstance(progress, bool) \
            else None
        self.bar: Any = None
        self.count = 0
        self.total = total
        self.desc = desc
        if self.callback is None and wants_bar(progress):
            try:
                from tqdm.auto import tqdm  # heavy: only when a bar is drawn
            except ImportError:
                if progress is True:         # asked for explicitly: say what is missing
                    raise MissingDependencyError("progress=True draws a bar with tqdm: pip "
                                                 "install tqdm") from None
                return                       # None means "a bar when possible"
            self.bar = tqdm(total=total, desc=desc, unit=unit, file=sys.stderr,
                            dynamic_ncols=True, leave=False)

    def step(self, text: str = "", n: int = 1) -> None:
        self.count += n
        if self.bar is not None:
            if text:
                self.bar.set_postfix_str(text[:60], refresh=False)
            self.bar.update(n)
        elif self.callback is not None:
            of = f"/{self.total}" if self.total is not None else ""
            self.callback(f"{self.desc} {self.count}{of}" + (f": {text}" if text else ""))

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
