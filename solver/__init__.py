"""lasercal.solver: product-of-exponentials kinematics and calibration.

The core of lasercal. It depends on neither ``collector`` nor ``vision``.
Lengths are millimetres and angles radians everywhere in this package.
"""

import os
import sys

# Our matrices are small (at most a few 10^4 x 10^2): a multi-threaded BLAS spends more on
# waking threads than it saves, and on a busy 2-core machine a 300 x 33 SVD took 80 ms
# threaded against 0.3 ms on one thread. One BLAS thread for the whole process. A BLAS reads
# its thread count when it loads, so the variables reach numpy's and scipy's BLAS (each has
# its own) loaded from now on, and threadpoolctl the ones already loaded; a limit set by
# threadpoolctl alone, before either had loaded, once reached neither (both ran 2 threads).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")
if "numpy" in sys.modules:
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=1, user_api="blas")
