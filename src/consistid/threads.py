"""BLAS thread hygiene: one thread for loops of small dense calls.

OpenBLAS and MKL start a pool of threads for every call, however small. In a loop of thousands of
small least-squares solves (an optimiser's iterations, a profile over a grid, a diagnosis's
refits) the hand-over costs more than the arithmetic, and on a loaded machine the threads of
several processes oversubscribe the cores: ``estimate_mounting`` on 2 000 samples took 78 s with
default threading on a busy 2-core machine and 2.3 s with one thread (issue 12). The functions
whose work is such a loop run under :func:`single_blas_thread`; large single calls (the QR of a
long regressor) keep the user's threading.
"""

from __future__ import annotations

import functools
from typing import Callable, TypeVar

from threadpoolctl import threadpool_limits

F = TypeVar("F", bound=Callable)


def single_blas_thread(function: F) -> F:
    """Run ``function`` with the BLAS thread pools limited to one thread (``threadpoolctl``),
    restoring the caller's limits afterwards, even on an exception."""

    @functools.wraps(function)
    def wrapper(*args, **kwargs):
        with threadpool_limits(limits=1, user_api="blas"):
            return function(*args, **kwargs)

    return wrapper  # type: ignore[return-value]
