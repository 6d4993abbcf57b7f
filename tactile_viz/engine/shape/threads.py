"""One large field evaluation spread over threads.

The GPIS mean's compiled correction releases the GIL (``nogil``) and a k-d tree query
takes ``workers``: the chunks of one query (a surface's grid) run on several cores at
once, and each chunk's numbers are the same whichever thread computes them.
"""

import os
from concurrent.futures import ThreadPoolExecutor

MOST_THREADS = 8


def evaluation_threads():
    """Threads one evaluation may use: ``OMP_NUM_THREADS`` when set (a benchmark's worker
    processes set 1: together they already fill the machine), else the CPUs this process
    may run on, at most :data:`MOST_THREADS`."""
    value = os.environ.get("OMP_NUM_THREADS", "").strip()
    if value.isdigit() and int(value) > 0:
        return int(value)
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cpus = os.cpu_count() or 1
    return max(1, min(MOST_THREADS, cpus))


def map_chunks(function, count, chunk):
    """``[function(start) for start in range(0, count, chunk)]``, the calls on up to
    :func:`evaluation_threads` threads (one call: no thread)."""
    starts = range(0, count, chunk)
    threads = min(evaluation_threads(), len(starts))
    if threads <= 1:
        return [function(start) for start in starts]
    with ThreadPoolExecutor(threads, thread_name_prefix="tactile_viz-evaluation") as pool:
        return list(pool.map(function, starts))


def tree_workers(count, least=4096):
    """``workers`` for a k-d tree query of ``count`` points: one below ``least`` (threads
    cost more than they save there), else :func:`evaluation_threads`."""
    return evaluation_threads() if count >= least else 1
