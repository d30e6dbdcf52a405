"""One BLAS thread for results that must be the same bits in every process.

A multi-threaded BLAS splits matrix products and factorisations by its thread count, so their
last bits depend on the process that runs them (a Dask worker runs one BLAS thread, the
command line as many as the machine has cores). Sampled wind profiles and the assembled
guidance problem are recorded and compared bit for bit across those processes; they are
computed with one thread (their matrices are small: a few hundred rows).
"""

from __future__ import annotations

import functools

from threadpoolctl import threadpool_limits

__all__ = ["one_blas_thread"]


def one_blas_thread(fn):
    """Decorator: run ``fn`` with the BLAS libraries of this process limited to one thread
    (restored afterwards)."""
    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        with threadpool_limits(limits=1, user_api="blas"):
            return fn(*args, **kwargs)
    return wrapper
