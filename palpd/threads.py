"""BLAS on one thread in every palpd process.

The learner's updates are many small matrix products; OpenBLAS's default of a
thread per core makes them 3–5× slower on a loaded 2-core machine (threads spin
and contend) and takes a core from the servo loop. palpd sets the limit itself:
the environment variables for BLAS libraries not loaded yet and for every
process palpd starts (the servo and learner processes inherit them), and
threadpoolctl for any already loaded in this process.
"""
from __future__ import annotations

import os

THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS",
                    "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")


def pin_blas_to_one_thread() -> None:
    for name in THREAD_VARIABLES:
        os.environ[name] = "1"
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # scikit-learn brings it; without it the variables still hold for what loads later
        return
    threadpool_limits(limits=1)


def blas_threads() -> int:
    """The largest thread count of the BLAS/OpenMP pools loaded in this process (1 when pinned)."""
    from threadpoolctl import threadpool_info

    return max((pool["num_threads"] for pool in threadpool_info()), default=1)
