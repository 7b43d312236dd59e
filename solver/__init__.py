"""lasercal.solver: product-of-exponentials kinematics and calibration.

The core of lasercal. It depends on neither ``collector`` nor ``vision``.
Lengths are millimetres and angles radians everywhere in this package.
"""

import numpy  # noqa: F401  (loads numpy's BLAS, so that the limit below reaches it)
import scipy.linalg  # noqa: F401  (scipy ships a BLAS of its own)
from threadpoolctl import threadpool_limits

# Our matrices are small (at most a few 10^4 x 10^2): a multi-threaded BLAS spends more on
# waking threads than it saves, and on a busy 2-core machine a 300 x 33 SVD took 80 ms
# threaded against 0.3 ms on one thread. One BLAS thread for the whole process. The limit
# reaches only libraries already loaded: before both imports above it reached none, and numpy's
# and scipy's BLAS each ran 2 threads.
threadpool_limits(limits=1, user_api="blas")
