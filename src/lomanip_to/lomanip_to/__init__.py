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
