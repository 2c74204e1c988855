"""Whole-body trajectory optimisation for the G1: centroidal dynamics with full kinematics.

Core library (no rclpy):

* :mod:`.model` - G1 from the Menagerie MJCF (Pinocchio) + CasADi kinematics/CoM/CMM.
* :mod:`.problem` - problem dataclasses (scene, keyframes, schedule, goals, options) + validation.
* :mod:`.fixtures` - YAML fixtures (``config/``: S1, S2, small test cases, solver defaults).
* :mod:`.transcription` - the symbolic knot window (dynamics, contacts, collisions, costs).
* :mod:`.discretize` - knot grid, bounds, parameters, warm start from keyframes.
* :mod:`.assembly` - sparse NLP assembled from the mapped window derivatives.
* :mod:`.solver` - ``solve(problem) -> TOResult`` (ipopt, homotopy stages, statistics).
* :mod:`.result` - result type with a dense controller grid; :mod:`.checks` - physics checks.
"""

import os as _os

# ipopt's linear algebra (MUMPS on CasADi's OpenBLAS, both built with OpenMP) runs single-threaded
# unless the user says otherwise.  Why: the window functions are already evaluated on 2 threads,
# and on a 2-core machine the extra BLAS/OpenMP threads only contend: ipopt's own time on
# case_lift_box went from 15.9 s to 6.8 s under load with one thread.  Set before CasADi loads its
# ipopt plugin (which happens at the first solver build, after this import).
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    _os.environ.setdefault(_var, "1")
