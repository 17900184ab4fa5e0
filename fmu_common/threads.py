"""One BLAS thread per process that runs a unit.

The units factorize and multiply small matrices (n < 1000): a threaded BLAS pool only adds start-up and
synchronization to each call, and where the cores are shared it made an LU of size 158 a hundred times
slower than on one thread. Environment variables such as OPENBLAS_NUM_THREADS are read
when the library is loaded, too late in a host that imported numpy first; threadpoolctl sets the size of
a pool already loaded.
"""


def limit_blas_threads() -> None:
    """Limit every BLAS library loaded in this process (numpy's, scipy's) to one thread.

    Called explicitly where a process or a unit starts: an FMI slave's construction, the `wingsim` command
    line, a sweep worker, a benchmark's entry point. Loads numpy and scipy.linalg first, so that their BLAS
    libraries are there to be limited; a library loaded later is not.
    """
    import numpy  # noqa: F401
    import scipy.linalg  # noqa: F401
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=1, user_api="blas")
