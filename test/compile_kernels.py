"""Compile the package's numba kernels into numba's cache, each in a process of its own.

``scripts/test.sh`` runs this before the test workers start: each worker would otherwise find
the cache empty on a fresh clone and compile the same kernels as the other, both cores busy for
the same ~35 s. Prints the seconds each took (a cache hit: under a second).
"""

from __future__ import annotations

import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np


def model_kernel() -> float:
    """The model's integration kernel (what every simulation, fit and node runs)."""
    from jetpipe_ros.model import compile_kernel

    return compile_kernel()


def chamber_rates() -> float:
    """The model's chamber mass balance on measured signals (the diagnosis's residuals)."""
    from jetpipe_ros.model import ModelParams, build_constants, kernel

    start = time.perf_counter()
    zeros = np.zeros(3)
    kernel.chamber_rates(build_constants(ModelParams()), zeros, zeros, zeros + 4e5,
                         zeros + 4e5, zeros)
    return time.perf_counter() - start


def plant_loop() -> float:
    """The stand-in hardware's own loop (the selfcheck's and the tests' "real" records)."""
    from jetpipe_ros.plant import Plant

    start = time.perf_counter()
    Plant().step(0.0)
    return time.perf_counter() - start


def main(jobs: int) -> None:
    start = time.perf_counter()
    with ProcessPoolExecutor(jobs) as pool:
        futures = {job.__name__: pool.submit(job) for job in (model_kernel, chamber_rates,
                                                               plant_loop)}
        took = ", ".join(f"{name} {future.result():.0f} s" for name, future in futures.items())
    print(f"[test] numba kernels ready in {time.perf_counter() - start:.0f} s ({took})",
          flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 2)
