"""Shared by every test: the helpers beside the tests import as top-level modules; under
pytest-xdist (the README's command runs one worker a core), each worker keeps its BLAS and
OpenMP pools to one thread, and so do the processes its tests start - two workers on two
cores with a pool of two threads each spent their time waiting on each other."""
import os
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).parent))

if os.environ.get("PYTEST_XDIST_WORKER"):
    for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(name, "1")
    from threadpoolctl import threadpool_limits
    threadpool_limits(1)
