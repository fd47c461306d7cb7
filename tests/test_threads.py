"""single_blas_thread limits BLAS to one thread inside and restores the caller's limits."""

import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from consistid.threads import single_blas_thread


def _blas_threads() -> list[int]:
    return [p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"]


def test_one_thread_inside_and_restored_after_even_on_error():
    import numpy  # noqa: F401  (loads the BLAS threadpoolctl inspects)

    if not _blas_threads():
        pytest.skip("no BLAS library visible to threadpoolctl")
    seen = []

    @single_blas_thread
    def work(fail: bool) -> int:
        seen.append(_blas_threads())
        if fail:
            raise RuntimeError("boom")
        return 7

    with threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()
        assert work(False) == 7
        with pytest.raises(RuntimeError, match="boom"):
            work(True)
        assert _blas_threads() == before
    assert seen == [[1] * len(before)] * 2
    assert work.__name__ == "work"
