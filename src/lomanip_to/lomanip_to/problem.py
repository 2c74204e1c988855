"""Problem description of the whole-body TO (plain dataclasses, no ROS) and its validation.

Everything the TO needs arrives here: scene objects (primitives, mass, inertia, pose), keyframes
(35-D G1 configuration + contacts + desired mid-foot xy), the contact schedule (contiguous phases
with the limbs in contact and what they touch, stance/walking flag, which objects move and how),
placement goals and the options (ablation switches).  :func:`validate_problem` raises
:class:`ProblemError` with an error code (values of ``lomanip_msgs/ErrorCode``) BEFORE any solve.

Conventions: world frame z up, metres, seconds, kg; quaternions (x, y, z, w) as in ROS/Pinocchio;
joint order = MuJoCo / Pinocchio order of g1.xml (29 joints).

Simplifications (named):
* An object's frame origin is taken as its centre of mass (``com`` must be ~0).
* Object primitives are boxes and cylinders; for collision a cylinder is treated as its bounding box.
* Objects not listed as moving in a phase are fixed in the world during that phase (their support
  forces are not modelled); a robot foot may stand on a fixed object's top face.
* An object ``attached`` to another (box riding on the trolley) moves rigidly with it and its mass
  and inertia are lumped into the carrier's rigid body for that phase.
"""

from __future__ import annotations

import io
import math
from contextlib import redirect_stdout
from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np

from .model import COP_MARGIN, FEET, HANDS, LIMBS

# lomanip_msgs/ErrorCode values (kept numerically identical; the conversion layer maps them)
SUCCESS = 1
INVALID_REQUEST = -1
UNKNOWN_OBJECT = -2
TO_NOT_CONVERGED = -6
TIMEOUT = -7
INVALID_TRAJECTORY = -11

STANCE = "stance"
WALKING = "walking"
FLOOR = "floor"

OBJECT_MODES = ("free", "supported", "rolling", "attached")

#: Reach model for the placement check: a placement must lie within this horizontal distance of a
#: keyframe base position and below this height above that keyframe's support.
REACH_XY = 1.0
REACH_Z = 1.8
WORKSPACE = ((-20.0, 20.0), (-20.0, 20.0), (-0.01, 3.0))


class ProblemError(ValueError):
    """Invalid TO input; ``code`` is a lomanip_msgs/ErrorCode value, ``where`` names the field."""

    def __init__(self, code: int, message: str, where: str = ""):
        super().__init__(f"[{code}] {where + ': ' if where else ''}{message}")
        self.code = code
        self.message = message
        self.where = where


@dataclass
class Primitive:
    """A box (``size`` = full lengths x, y, z) or cylinder (``size`` = height, radius, as
    shape_msgs/SolidPrimitive) posed in the object frame (position + yaw about the object z)."""

    kind: str
    size: tuple
    position: tuple = (0.0, 0.0, 0.0)
    yaw: float = 0.0

    def half_extents(self) -> np.ndarray:
        if self.kind == "box":
            return 0.5 * np.asarray(self.size, float)
        if self.kind == "cylinder":
            h, r = self.size
            return np.array([r, r, 0.5 * h], float)
        raise ProblemError(INVALID_REQUEST, f"unknown primitive kind {self.kind!r}", "primitive")


@dataclass
class SceneObject:
    id: str
    object_class: str
    movable: bool
    position: tuple
    quat_xyzw: tuple = (0.0, 0.0, 0.0, 1.0)
    mass: float = 0.0
    com: tuple = (0.0, 0.0, 0.0)
    inertia: tuple = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    primitives: list = field(default_factory=list)
    #: for ``rolling`` objects: the rear axle position in the object frame (no lateral slip there)
    rear_axle: tuple = (0.0, 0.0, 0.0)

    def yaw(self) -> float:
        x, y, z, w = self.quat_xyzw
        return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))

    def rpy(self) -> np.ndarray:
        from .model import quat_xyzw_to_rot, rot_to_rpy

        return rot_to_rpy(quat_xyzw_to_rot(self.quat_xyzw))

    def bottom_z(self) -> float:
        """Lowest point of the primitives relative to the object origin (object kept level)."""
        return min(p.position[2] - p.half_extents()[2] for p in self.primitives)

    def top_z(self) -> float:
        return max(p.position[2] + p.half_extents()[2] for p in self.primitives)

    def footprint_half(self) -> np.ndarray:
        """Half extents in x, y of the union of primitives (object frame, about the origin)."""
        hx = max(abs(p.position[0]) + p.half_extents()[0] for p in self.primitives)
        hy = max(abs(p.position[1]) + p.half_extents()[1] for p in self.primitives)
        return np.array([hx, hy])

    def bottom_corners(self) -> np.ndarray:
        """(4, 3) corners of the footprint at the bottom (object frame): what rests on a support."""
        hx, hy = self.footprint_half()
        bz = self.bottom_z()
        return np.array([[hx, hy, bz], [hx, -hy, bz], [-hx, hy, bz], [-hx, -hy, bz]])

    def inertia_matrix(self) -> np.ndarray:
        I = np.asarray(self.inertia, float)
        if I.shape == (3,):
            I = np.diag(I)
        if not np.any(I) and self.primitives:  # solid box estimate from the first primitive
            a, b, c = 2 * self.primitives[0].half_extents()
            I = self.mass / 12.0 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
        return I


@dataclass
class ContactSpec:
    """A contact of one limb: ``position`` (world) on ``object_id`` with outward ``normal``."""

    limb: str
    object_id: str
    position: tuple
    normal: tuple = (0.0, 0.0, 1.0)
    #: rad about the world z: where a foot's sole points (its forward axis) at this foothold; None:
    #: free. Set by the planner's footsteps; the TO's walking nominal turns the base with the feet
    #: (discretize, session 53), it does not constrain the sole's yaw
    heading: float | None = None


@dataclass
class Keyframe:
    subtask_index: int
    base_position: tuple
    base_quat_xyzw: tuple
    joints: tuple  # 29 values, model order
    contacts: list = field(default_factory=list)
    desired_foot_xy: tuple | None = None
    reference_object_id: str = ""
    prompt: str = ""
    #: time of the keyframe in the trajectory; None = end of its subtask
    time: float | None = None

    def x(self) -> np.ndarray:
        from .model import quat_xyzw_to_rot, rot_to_rpy

        x = np.zeros(35)
        x[:3] = self.base_position
        x[3:6] = rot_to_rpy(quat_xyzw_to_rot(self.base_quat_xyzw))
        x[6:] = self.joints
        return x


@dataclass
class ObjectMotion:
    """How a movable object moves in a phase (objects not listed are fixed).

    * ``free``: single rigid body under gravity and the robot's contact wrenches (carried).
    * ``supported``: rigid body resting on ``support`` (``floor`` or a fixed object's top) with
      four corner forces (patch contact), may slide.
    * ``rolling``: like supported, plus nonholonomic wheels: no longitudinal friction and zero
      lateral velocity at the rear axle (trolley).
    * ``attached``: rigidly attached to ``attached_to`` (another moving object).
    """

    mode: str = "free"
    support: str = FLOOR
    attached_to: str = ""


@dataclass
class ContactPhase:
    start: float
    end: float
    phase_type: str = STANCE  # "stance" | "walking"
    subtask_index: int = 0
    #: limb -> ContactSpec (object_id "floor" or a SceneObject.id; position optional for feet)
    contacts: dict = field(default_factory=dict)
    objects: dict = field(default_factory=dict)  # object id -> ObjectMotion


@dataclass
class PlacementGoal:
    object_id: str
    position: tuple
    yaw: float = 0.0
    #: time at which the goal should hold; None = end of the trajectory
    time: float | None = None
    weight: float = 1e3


#: joint groups of the TO's torque rows (lomanip_to.model.G1Model.torque_row_joints)
TORQUE_GROUPS = ("left_foot", "right_foot", "left_hand", "right_hand", "waist")

#: Hessians the solver can hand ipopt (Options.guide_hessian / final_hessian, assembly.AssembledNLP.hessian)
HESSIANS = ("exact", "cost")

#: forms of the collision homotopy's surrogate (Options.homotopy_form)
HOMOTOPY_FORMS = ("auto", "slacks", "penalty")


@dataclass
class Options:
    use_keyframe_base_cost: bool = True
    use_keyframe_foot_cost: bool = True
    use_keyframe_warm_start: bool = True
    #: refine the keyframe warm start into a stepping motion (feet on footholds, per-knot IK;
    #: warm_start.py); only with use_keyframe_warm_start
    stepping_warm_start: bool = True
    collision_hard_constraint: bool = True
    collision_penalty: bool = True
    collision_homotopy: bool = True
    #: how the homotopy's surrogate enters: "slacks" (rows F - 1 + s >= 0, one slack per pair, cost
    #: w_hom (w_slack s^2 + max(1 - F, 0)^2)), "penalty" (no slacks: the same cost minimised over s,
    #: w_hom (w_slack + 1) max(1 - F, 0)^2; in the final stage the hard rows imply F >= 1, so it
    #: drops the surrogate) or "auto": "penalty" in an NLP in which an object is carried while the
    #: robot walks, else "slacks".  Measured (docs/to.md, session 15): S1's carry converges only
    #: without slacks (thousands of slacks on inactive rows held ipopt's barrier at 1-10); S1's last
    #: subtask and the demo's push converge and execute better with them.
    homotopy_form: str = "auto"
    max_iterations: int = 500
    output_rate: float = 100.0
    #: knot spacing targets (s) for stance and walking phases (phase-wise sizing)
    dt_stance: float = 0.2
    dt_walking: float = 0.1
    #: knot spacing (s) of a stance phase in which an object leaves its support into the hands (a
    #: lift); 0 = dt_stance. Why: S1's box and body rose 0.25 m in one 0.2 s interval
    dt_lift: float = 0.0
    #: knot spacing (s) of a stance phase at whose end a hand makes a new contact (the reach before
    #: a grasp or a push); 0 = dt_stance. Why: in S1's grab from the graph (session 56) the arms swung
    #: over the shelf's edge between 0.2 s knots: the dense motion passed the left wrist 7.4 cm through
    #: the shelf and carried 1.41 kg m^2/s of angular momentum the plan did not (docs/to.md, session 57)
    dt_reach: float = 0.0
    tol: float = 1e-4
    constr_tol: float = 1e-4
    time_limit: float = 600.0
    #: stall acceptance of a final stage, for when ipopt wanders along a feasible valley without
    #: meeting its dual test (its violation oscillating between 1e-6 and 1e-3, say): stop when the
    #: best feasible iterate (violation within constr_tol) already existed ``stall_iterations``
    #: iterations ago and no feasible iterate since has lowered the objective by more than
    #: ``stall_rtol`` (relative); the stage then returns that best feasible iterate
    #: ("Feasible_Objective_Stalled").  Not a KKT certificate (docs/to.md); 0 switches it off.
    stall_iterations: int = 30
    stall_rtol: float = 1e-2
    #: a final stage that reaches max_iterations with a feasible iterate (violation within
    #: constr_tol; tracked only while stall_iterations > 0) returns its best feasible iterate
    #: ("Feasible_At_Iteration_Cap") instead of failing.  Why: S1's first subtask from prompts
    #: ended at the cap on a feasible iterate (violation 5e-6, objective still falling) and the
    #: whole plan failed there (session 34).  Not a KKT certificate, like the stall; the physical
    #: checks still decide success.  False: the cap fails the stage, as before session 35
    accept_feasible_at_cap: bool = True
    #: a final stage that ipopt ends by itself without optimality (restoration failed, problem
    #: declared locally infeasible, step too small: result.STOPPED_EARLY_STATUSES) after a feasible
    #: iterate (violation within constr_tol; tracked only while stall_iterations > 0) returns its
    #: best feasible iterate ("Feasible_Before_Solver_Stop"). Why: S2 5.0 kg at yaw +-0.6 ended the
    #: pick "Infeasible_Problem_Detected" on points within 7e-6 of every row (session 40). Not a KKT
    #: certificate; the physical checks still decide success. False: such a stop fails the stage
    accept_feasible_at_solver_stop: bool = True
    #: m/s: over the LIFT_OFF_KNOTS knots after an object leaves its support it rises at least this
    #: fast and moves sideways at most this fast (0 = off: only the gentle start's speed bounds).
    #: Why: S2's generated lift raised the box 6 mm in 0.8 s while moving it 4-8 cm sideways;
    #: executed, the box dragged on the table top and slipped out of the hands (docs/execution.md,
    #: session 35)
    lift_off_vertical: float = 0.0
    #: a movable object at rest ("fixed": untouched by the plan's motions) that a hand touches gets
    #: its support's corner forces (inside their friction cones) and its dynamics at rest, so the
    #: hands' net force on it is what its support can hold. Off, it is an immovable support: S2's
    #: plan leant on its box with 36 N forwards (the table's friction holds about 20 N), and executed
    #: the robot ran 12 cm ahead of its plan onto its toes before the lift (docs/to.md, session 36).
    #: Off by default: on in the S1 and S2 fixtures, where it cost two S1 grid cells their pick
    #: (5.0 kg; yaw 0.6) while S1 nominal passes every check with it (docs/to.md, session 37)
    resting_object_dynamics: bool = False
    #: Hessian ipopt gets in the homotopy guide stage and in the final stage: "exact" (Lagrangian)
    #: or "cost" (the cost's Hessian only, constraint curvature dropped; see assembly)
    guide_hessian: str = "exact"
    final_hessian: str = "exact"
    print_level: int = 0
    #: a converged guide hands the final stage a primal-dual warm start (barrier 1e-4) only when its
    #: point violates the final stage's rows by at most this much; farther, the final stage starts
    #: from the guide's point with a fresh barrier. Why 1e-2: farther away, the small barrier sent
    #: S1's first subtask from the graph (keyframes of session 6) wandering (objective 150 -> 8e3)
    #: into a MUMPS factorisation that stalled for minutes; started cold from the same point the
    #: stage took 178 iterations, 48 s. On S1 the guide's point misses the hard collision rows by
    #: 1.2-2.5 cm, so every final stage starts cold. With 1.0 (any start): S1 2.5 kg / yaw 1.2
    #: converges and passes every check (982 iterations; at the default its pick stops at the cap),
    #: S1 5.0 kg gets past its pick and stops in the carry, S1 nominal takes 1015 iterations instead
    #: of 1271 but fails the check between knots (1.45, limit 1), and S2 nominal's faster plan falls
    #: when executed. An option, not the default (docs/to.md, session 39)
    final_warm_start_max_violation: float = 1e-2
    #: a final stage that started warm (from its guide's primal-dual point) and ends without a
    #: feasible iterate is solved once more from the guide's primal point alone, barrier from
    #: scratch: the two starts take different paths through this non-convex problem, and the cold
    #: one has converged where the warm one crawled to its cap (docs/to.md, session 56). Costs a
    #: second final stage only when the first fails
    final_cold_retry: bool = False
    #: an object still held (``free``) after its placement goal's time is held at the goal: the
    #: goal's cost at every such knot, not only at the goal's knot and the last one. Why: S1 from
    #: prompts lifts the basket to its goal, then over the 1 s hold its plan let it sag 6 cm and
    #: lifted it back in the last 0.2 s interval (the last knot has the goal's cost too); executed,
    #: the right hand lost the basket in that re-lift in 2 of 3 worlds (docs/to.md, session 57)
    hold_placement_goals: bool = False
    #: collision rows (robot-object, carried object, floor, self) farther than this (m) from their
    #: bound at a stage's start are left out of that stage's NLP, their homotopy slacks pinned at 0;
    #: a stage whose result violates a left-out row is solved again, screened anew (at most
    #: ``solver.MAX_RESCREENS`` times). 0 = every row in every stage (``screening``). Why: the
    #: demo's push has 21567 rows in its final stage, 7680 with 5 cm; it plans in half the time
    #: (docs/to.md, session 58)
    collision_screen_distance: float = 0.05
    #: solve subtask by subtask (at rest at subtask boundaries), stitch, then polish the whole horizon
    subtask_segments: bool = True
    #: also cut a subtask's segment at its internal rest points (:func:`lomanip_to.solver.rest_points`:
    #: the end of a double stance of at least 0.4 s before walking starts or the hands take a new
    #: hold), so each NLP is shorter and starts and ends at rest.  Off: on S1's carry the piece
    #: after the lift did not converge where the whole subtask did (docs/to.md, session 9)
    rest_segments: bool = False
    #: a subtask that opens with a lift (an object goes free in its first phase) starts its segment
    #: after that phase: the lift is solved with the segment before it, whose last knot otherwise
    #: stands at rest without the object's weight in its hands, and the next segment must start from
    #: there at rest holding it (S2's carry: the robot-and-box CoM 2 cm past the soles at its first
    #: knot, infeasible; docs/to.md, session 33). Off by default (measured on S2 only)
    lift_with_previous_segment: bool = False
    #: each subtask segment carries variables only for the objects that move or are touched by a
    #: hand in it (:func:`lomanip_to.solver.segment_moving`); the others stand as static scene
    #: objects at the poses the segments before left them, and the stitch fills their variables
    #: (pose held, velocity and support forces zero) on the whole horizon. Why: S1 with the basket
    #: lifted at its end made the basket a moving object of every segment, every segment's NLP
    #: changed and the solve took 974 s against 505 (docs/to.md, session 42). Off by default: it
    #: changes every segmented plan (S2's executed nominal plan included), measured on S1 only
    segment_moving_objects: bool = False
    #: iteration cap of the whole-horizon polish after the subtask solves (0 = keep the stitched one).
    #: Off by default: on S1 it never converged within 60 iterations and cost 90-150 s a run
    #: (docs/to.md); the stitched trajectory is evaluated on the whole problem's rows and checked as it is.
    polish_iterations: int = 0
    #: collision sphere groups checked against objects ("minimal collision set"); the physical check
    #: counts every sphere, so a group left out here can fail it (S2's upper arm, 60 mm into the box;
    #: S1's head, 113 mm into the lifted box)
    collision_groups: tuple = ("left_foot", "right_foot", "left_shin", "right_shin", "left_thigh",
                               "right_thigh", "pelvis", "torso", "head", "left_hand", "right_hand",
                               "left_forearm", "right_forearm", "left_upper_arm", "right_upper_arm")
    self_collision: bool = True
    #: more self-collision pairs for the hands (:func:`lomanip_to.discretize.self_pairs`): each hand
    #: and wrist against the other side's hip and thigh, the torso's lower front and its own shin.
    #: Why: S1's 2.5 kg / 0.6 rad plan parked the left hand on the body with no pair for it, 14 mm into
    #: the right hip's sphere at 13.0 s and the wrist 15 mm into the left shin; executed, the hand
    #: jammed between the torso and the right hip in the step onto the box and the robot fell at
    #: 14.0 s (docs/execution.md, session 44). Off by default: it changes every plan
    hand_body_self_pairs: bool = False
    #: more self-collision pairs for the arms on their own side (:func:`lomanip_to.discretize.self_pairs`):
    #: forearm and upper arm against the torso (its upper and lower front), the thigh's upper sphere
    #: and the hip's front; hand and wrist against the hip's front. Why: S1 nominal's plan of session
    #: 48 stepped onto the box with its left upper arm 8.5 cm inside the torso sphere, the right
    #: forearm 3.8 cm inside the right thigh's and the left hand tip in the left hip's front, pairs
    #: without rows; executed, the rising thigh struck the hand (docs/to.md, session 48). The rows
    #: hold only while that side's hand touches nothing (a hand on an object is placed by its grip;
    #: with them at every knot S1's carry did not converge, session 48); the physical check counts
    #: them at every knot. Off by default: it changes every plan (``subtask_options`` sets it for some)
    arm_body_self_pairs: bool = False
    #: the forearm spheres (elbow to wrist) stay out of an object while that side's hand touches it
    #: (False: off with the hand's own spheres, as before). Why: with them off, S1's and S2's plans
    #: carried the box with the wrist links 3-8 cm inside it on MuJoCo's meshes; executed, the elbows
    #: and wrists pressed on the box with 20-140 N beside the hands' forces (docs/execution.md,
    #: session 40)
    forearm_clear_of_held_object: bool = False
    #: m: a hand in contact holds its hand point (model.HAND_POINT, on the wrist-yaw axis) this far
    #: outside the touched surface along its normal, and its force acts at the surface point below
    #: it (0: the hand point on the surface, as before). Named simplification: the hand as a ball of
    #: this radius about its hand point. Why: the rubber hand's inner face is 4.5 cm from the wrist
    #: axis (lomanip_sim robot_model: hand box centre 1.2 cm towards the palm, half thickness 3.3 cm),
    #: so with the point on the surface the plans hold their wrists and forearms 3-8 cm inside the
    #: box they carry (docs/execution.md, session 40). Offline option
    hand_standoff: float = 0.0
    #: rad: the waist yaw stays within +-this (0 = the G1's +-2.62). A posture choice, not a joint
    #: limit: S1's carry turned the torso -2.2 rad and held the box over the shoulder (docs/to.md,
    #: session 16)
    waist_yaw_range: float = 0.0
    #: m: a stance foot on the floor stays inside this square round its foothold in the contact
    #: schedule (0 = anywhere on the floor). The footholds are only a guess otherwise: converged
    #: plans of the demo push moved a foot up to 29 cm, into stances 8.5 cm wide that left one foot
    #: carrying the robot; executed under physics, those fell, the two plans within 7 cm did not
    #: (docs/to.md, session 9)
    foothold_radius: float = 0.06
    #: Balance margins, so the whole-body controller can execute the plan (docs/execution.md,
    #: session 10). m: in a single stance the CoM's ground point stays along the stance sole within
    #: its force points plus ``single_support_com_margin`` and within ``single_support_com_lateral``
    #: of the sole's centre line across it; in a double stance it stays ``double_support_com_margin``
    #: inside the two soles' force points; the horizontal rate of angular momentum about the CoM over
    #: the weight (how far the centroidal moment pivot leaves the centre of pressure) stays within
    #: ``max_cmp_offset``. None (0 for the last) switches one off. Why: the demo pushes that fell
    #: under physics balanced on angular momentum (CMP up to 6 cm from the CoP), which the controller
    #: does not track, and stood with the CoM on a heel's force points
    single_support_com_margin: float | None = 0.0
    single_support_com_lateral: float | None = 0.08
    double_support_com_margin: float | None = 0.02
    max_cmp_offset: float = 0.005
    #: m: the soles' toe-side force points lie this far inside the toe edge (the heel and the sides
    #: keep lomanip_to.model.COP_MARGIN, 2 / 1 cm), so a planned centre of pressure stays this far
    #: behind the toes. Why: S1's plans lift the box and take the first carrying step with both
    #: feet's centre of pressure on the front force points (6.5 cm ahead of the sole centre);
    #: executed, the stance foot rolled onto its toe edge and the robot tipped forward at 5.1 s.
    #: With 0.04 the executed CoM stays within 3 cm of the plan through the lift and the first step
    #: (docs/execution.md, session 38). The default keeps every plan as before
    cop_margin_front: float = float(COP_MARGIN[0])
    #: m: the soles' force points lie this far inside the sole's sides (the heel's are 2.5 cm and the
    #: toe's 3 cm from the sole's centre line), so a planned centre of pressure stays this far from a
    #: side edge. Why: S1's plan at 2.5 kg / 1.2 rad carried a single stance on the outer toe point,
    #: 1 cm inside the edge; executed, that sole's centre of pressure reached the edge and the robot
    #: rolled over it (fell at 2.86 s). Solved with 0.015 that cell's plan executes to task success
    #: (docs/execution.md, session 46). The default keeps every plan as before
    cop_margin_side: float = float(COP_MARGIN[1])
    #: the double-stance margin above counts the objects the hands carry (free in the phase, held
    #: by a hand) with the robot: their weight, at arm's length, is what moves the centre of
    #: pressure to the toes. Off by default (measured on S2 only, docs/to.md, session 34). Why: S2's
    #: plan held the box with the robot's CoM 2 cm inside the soles and the feet's centre of
    #: pressure on the force points' front edge; under physics it tipped onto its toes at the grasp
    load_in_double_support_margin: bool = False
    #: rad: both knees at least this bent after the first phase (0 = the G1's limit). Why: with a
    #: stance knee at 0.17 rad the executed pelvis, 5 mm above its plan, could only be carried by
    #: lifting the heel; the foot rolled onto its toes and the robot fell backwards (docs/execution.md,
    #: session 10)
    min_knee_bend: float = 0.0
    #: joint groups ("waist", "left_hand", "right_hand", "left_foot", "right_foot") whose torque rows
    #: add the inertia of the links the joint carries to the quasi-static torque (the others stay
    #: quasi-static). The waist, by default: S1's lift took its pitch to 1.27 of the limit with
    #: quasi-static rows. Each dynamic group costs time per iteration (waist +8 %, all +25 %), and
    #: with the arms dynamic S1's carry did not converge (docs/to.md, session 12). The physical
    #: check counts the inertia of every joint whatever this says
    inertial_torque_groups: tuple = ("waist",)
    #: fraction of each G1 joint torque limit the TO's torque rows allow at the knots (both the
    #: quasi-static and the inertial rows). 0.8 leaves room for the inertia the quasi-static rows
    #: leave out and for the motion between knots; a smaller value leaves the controller headroom
    #: for its feedback (S1's dense plan needs up to 0.99 of the waist pitch's limit at 0.8)
    torque_margin: float = 0.8
    #: kg m^2/s: the angular momentum of each interval's velocity, taken at the interval's first knot,
    #: stays within this of the momentum at its last knot (0 = off). The dynamics hold at knots
    #: 0.1-0.2 s apart, and a velocity that carries little momentum at one end and a lot at the
    #: other swings the body between them: S1's lift and carry did, and the densified motion a
    #: controller tracks carried 3-5 kg m^2/s the plan did not (docs/to.md, session 19). Costs one
    #: more momentum evaluation per knot
    interval_momentum_tolerance: float = 0.0
    #: rad/s^2: bound on the change of the base's rotation rates and the waist and arm joint speeds
    #: from one knot interval to the next, over the interval (0 = off). The legs are left free (a
    #: step's swing needs them). Why: S1's passing plans lifted and carried the box with arm
    #: accelerations up to 200 rad/s^2 between knots (the pushes that execute: under 20); such a
    #: plan holds its dynamics at the knots only (docs/to.md, session 19)
    upper_body_acceleration_limit: float = 0.0
    #: rad/s: bound on the waist and arm joint speeds at every knot (0 = off; the TO's bound of
    #: 20 rad/s on every joint always applies, as the model file gives none). Why: with the hands
    #: held on the box (the grip rows) S1's plans still turned a shoulder at up to 15 rad/s in the
    #: lift; the pushes that execute stay under 2 rad/s. On S1 it did not yet give a plan that
    #: executes (docs/to.md, session 23)
    upper_body_speed_limit: float = 0.0
    #: m: while an object is carried, the TO's collision rows keep it this far from every body sphere
    #: but the hands and forearms (0 = off: only the shins' and feet's 3 cm). Why: the TO checks
    #: collisions at its knots; S1's plans held the box against the torso, head and upper arms at
    #: every knot (clearance 0) and between knots it passed up to 15 cm through them (docs/to.md,
    #: session 19)
    carried_object_clearance: float = 0.0
    #: m: the TO's collision rows keep the pelvis, torso, head and thigh spheres this far from every
    #: object (0 = off; the feet and shins keep their own 3 cm, LEG_OBJECT_CLEARANCE). Why: those
    #: spheres sit inside the meshes the simulator collides (the torso mesh 1.7 cm past its spheres),
    #: and the rows hold only at the knots: S2's nominal plan kept them at 0.0 cm from the table top
    #: and a table leg at 4.7-5.0 s, and between the knots 4.8 and 5.0 s the left hip's meshes cut
    #: 3.9 cm into the leg; executed, the left hip struck the table and the robot fell (session 49)
    body_object_clearance: float = 0.0
    #: m: the TO's collision rows keep the hand spheres this far from every object no hand touches
    #: in the schedule (a shelf, a table; 0 = off). Why: the simulator collides a box round each
    #: hand whose corners lie up to 4.3 cm outside the TO's two hand spheres; S1's plan from
    #: prompts reached past a shelf leg with those corners 2-3 cm inside it, and executed, the wrist
    #: caught on the shelf and the robot fell (session 54)
    hand_object_clearance: float = 0.0
    #: m: the nominal of an object carried free comes to at most this horizontal distance from the
    #: base (over ``CARRY_REACH_BLEND`` s after it leaves its support and back before it is set down;
    #: 0 = off: it keeps its pose relative to the base from the grasp).  Why: S2's box nominal stayed
    #: at the pick's reach, 0.5 m ahead, so the warm start leaned the base 13 cm towards the table
    #: to hold it upright (docs/to.md, session 27)
    carry_reach: float = 0.0
    #: m: an object set down at a placement goal's time lies within this distance (in x and in y)
    #: of the goal: hard rows (0 = off: the goal is a cost only, weight ``PlacementGoal.weight``).
    #: Why: with the cost alone S2's stalled carry set the box down 31 cm short of the deck's goal
    #: (docs/to.md, session 27)
    placement_tolerance: float = 0.0
    weights: dict = field(default_factory=dict)
    #: {subtask index: {option: value}}: options of the segments that solve one subtask
    #: (``subtask_segments``), e.g. ``{2: {arm_body_self_pairs: true}}``; the stitched whole horizon
    #: is evaluated and checked with the problem's own options. Why: a row set that one subtask needs
    #: changed every subtask's solve path when set for all (S1 with arm_body_self_pairs, session 48)
    subtask_options: dict = field(default_factory=dict)
    #: extra ipopt options (expert use; e.g. {"mu_strategy": "monotone"})
    ipopt: dict = field(default_factory=dict)

    def replaced(self, **kw) -> "Options":
        return replace(self, **kw)


def _check_subtask_options(prob, model) -> None:
    """Options.subtask_options names subtasks of the schedule and options that exist, with valid values."""
    subs = prob.options.subtask_options
    if not isinstance(subs, dict):
        raise ProblemError(INVALID_REQUEST, "options.subtask_options must map subtask indices to options", "options")
    known = {ph.subtask_index for ph in prob.phases}
    names = {f.name for f in fields(Options)} - {"subtask_options"}
    for sub, over in subs.items():
        if sub not in known:
            raise ProblemError(INVALID_REQUEST, f"options.subtask_options: no subtask {sub!r} in the schedule "
                                                f"(subtasks: {sorted(known)})", "options")
        bad = sorted(set(over or {}) - names) if isinstance(over, dict) else [repr(over)]
        if bad:
            raise ProblemError(INVALID_REQUEST, f"options.subtask_options[{sub}]: unknown option(s) {', '.join(bad)}",
                               "options")
        validate_problem(replace(prob, options=prob.options.replaced(**over, subtask_options={})), model)


@dataclass
class Problem:
    objects: list
    keyframes: list
    phases: list
    initial_configuration: tuple  # 35-D x (p, rpy, 29 joints) or None
    placement_goals: list = field(default_factory=list)
    options: Options = field(default_factory=Options)
    name: str = ""

    def object(self, oid: str) -> SceneObject:
        for o in self.objects:
            if o.id == oid:
                return o
        raise ProblemError(UNKNOWN_OBJECT, f"unknown object id {oid!r}", "objects")

    @property
    def duration(self) -> float:
        return self.phases[-1].end if self.phases else 0.0

    def moving_object_ids(self) -> list:
        ids: list = []
        for ph in self.phases:
            for oid in ph.objects:
                if oid not in ids:
                    ids.append(oid)
        return ids

    def keyframe_time(self, kf: Keyframe) -> float:
        if kf.time is not None:
            return float(kf.time)
        ends = [ph.end for ph in self.phases if ph.subtask_index == kf.subtask_index]
        return max(ends) if ends else self.duration


# ----------------------------------------------------------------------------------------------
def _finite(arr, n: int | None, where: str) -> np.ndarray:
    a = np.asarray(arr, float).reshape(-1)
    if n is not None and a.size != n:
        raise ProblemError(INVALID_REQUEST, f"expected {n} values, got {a.size}", where)
    if not np.all(np.isfinite(a)):
        raise ProblemError(INVALID_REQUEST, f"non-finite value (NaN/inf) in {a.tolist()}", where)
    return a


#: ipopt options a request cannot set: Options.max_iterations and time_limit set the first three,
#: and MUMPS is the only linear solver installed
RESERVED_IPOPT_OPTIONS = ("max_iter", "max_wall_time", "max_cpu_time", "linear_solver")


#: Options fields that are tuples (YAML gives lists)
TUPLE_OPTIONS = ("collision_groups", "inertial_torque_groups")


def option_item(name: str, value):
    """(Options field name, value) of one option as a task file or YAML text names it:
    ``solver_options`` is ``ipopt`` (YAML's yes/no booleans become ipopt's words), list-valued
    tuple fields become tuples."""
    if name == "solver_options":
        return "ipopt", {str(n): ("yes" if x else "no") if isinstance(x, bool) else x for n, x in (value or {}).items()}
    if name in TUPLE_OPTIONS and isinstance(value, list):
        return name, tuple(value)
    return name, value


def parse_option_value(text: str):
    """A solver option's text value as ipopt wants it: int, else float, else the string."""
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


_IPOPT_CHECKED: dict = {}


def check_ipopt_options(opts: dict) -> None:
    """Raise INVALID_REQUEST unless ipopt accepts every option (name and value).

    Why: ipopt only reads its options when a solver is built, minutes into a long request; here a
    one-variable NLP is built with them (milliseconds; each set is checked once per process)."""
    if not opts:
        return
    reserved = sorted(set(opts) & set(RESERVED_IPOPT_OPTIONS))
    if reserved:
        raise ProblemError(INVALID_REQUEST, f"options.solver_options: {', '.join(reserved)} cannot be set here "
                                            "(max_iterations and time_limit set the iteration and time limits; "
                                            "MUMPS is the only linear solver)", "options")
    key = tuple(sorted((str(k), repr(v)) for k, v in opts.items()))
    if key not in _IPOPT_CHECKED:
        import casadi as ca

        x = ca.MX.sym("x")
        printed = io.StringIO()  # CasADi hands ipopt's messages to Python's sys.stdout
        with redirect_stdout(printed):
            try:
                ca.nlpsol("option_check", "ipopt", {"x": x, "f": x * x},
                          {"print_time": False, "ipopt": {"print_level": 0, "sb": "yes", **opts}})
                _IPOPT_CHECKED[key] = ""
            except RuntimeError as exc:
                _IPOPT_CHECKED[key] = str(exc).strip().splitlines()[-1].split(": ", 1)[-1]
        if _IPOPT_CHECKED[key]:  # ipopt says what is wrong with a value on stdout, not in the exception
            said = [ln.strip() for ln in printed.getvalue().splitlines() if ln.startswith("Setting:")]
            _IPOPT_CHECKED[key] = f"options.solver_options {opts} rejected by ipopt: {(said or [_IPOPT_CHECKED[key]])[0]}"
    if _IPOPT_CHECKED[key]:
        raise ProblemError(INVALID_REQUEST, _IPOPT_CHECKED[key], "options")


def check_weights(weights: dict) -> None:
    """Raise INVALID_REQUEST for a cost weight the TO does not have, or one that is negative or not
    finite (a typo would otherwise be ignored, and a negative weight rewards what it should cost)."""
    from .discretize import DEFAULT_WEIGHTS

    for name, value in (weights or {}).items():
        if name not in DEFAULT_WEIGHTS:
            raise ProblemError(INVALID_REQUEST, f"options.weights: unknown weight {name!r} (known: "
                                                f"{', '.join(sorted(DEFAULT_WEIGHTS))})", "options")
        if not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
            raise ProblemError(INVALID_REQUEST, f"options.weights: {name} must be a finite number >= 0, "
                                                f"not {value!r}", "options")


def validate_problem(prob: Problem, model=None) -> None:
    """Check a problem before solving; raise :class:`ProblemError` on the first defect."""
    for name in ("guide_hessian", "final_hessian"):
        if getattr(prob.options, name) not in HESSIANS:
            raise ProblemError(INVALID_REQUEST, f"options.{name} must be one of {', '.join(HESSIANS)}, "
                                                f"not {getattr(prob.options, name)!r}", "options")
    if prob.options.homotopy_form not in HOMOTOPY_FORMS:
        raise ProblemError(INVALID_REQUEST, f"options.homotopy_form must be one of {', '.join(HOMOTOPY_FORMS)}, "
                                            f"not {prob.options.homotopy_form!r}", "options")
    check_ipopt_options(prob.options.ipopt)
    check_weights(prob.options.weights)
    _check_subtask_options(prob, model)
    bad = [g for g in prob.options.inertial_torque_groups if g not in TORQUE_GROUPS]
    if bad:
        raise ProblemError(INVALID_REQUEST, f"options.inertial_torque_groups: unknown group(s) {', '.join(map(repr, bad))} "
                                            f"(known: {', '.join(TORQUE_GROUPS)})", "options")
    for name, hi, rule in (("interval_momentum_tolerance", np.inf, ">= 0 (0 = off)"),
                           ("upper_body_acceleration_limit", np.inf, ">= 0 (0 = off)"),
                           ("upper_body_speed_limit", np.inf, ">= 0 (0 = off)"), ("carry_reach", 1.0, "in [0, 1] m (0 = off)"),
                           ("placement_tolerance", 1.0, "in [0, 1] m (0 = off)"),
                           ("carried_object_clearance", 0.2, "in [0, 0.2] m (0 = off)"),
                           ("body_object_clearance", 0.2, "in [0, 0.2] m (0 = off)"),
                           ("hand_object_clearance", 0.2, "in [0, 0.2] m (0 = off)"),
                           ("dt_lift", 1.0, "in [0, 1] s (0 = off)"),
                           ("dt_reach", 1.0, "in [0, 1] s (0 = off)"), ("cop_margin_front", 0.12, "in [0, 0.12] m"),
                           ("cop_margin_side", 0.02, "in [0, 0.02] m"),
                           ("hand_standoff", 0.1, "in [0, 0.1] m"),
                           ("final_warm_start_max_violation", np.inf, ">= 0"),
                           ("collision_screen_distance", 1.0, "in [0, 1] m (0 = off)"),
                           ("torque_margin", 1.0, "in (0, 1]")):
        val = getattr(prob.options, name)
        low_ok = val > 0 if rule.startswith("in (") else val >= 0  # "(": the interval is open at 0
        if not (np.isfinite(val) and low_ok and val <= hi):
            raise ProblemError(INVALID_REQUEST, f"options.{name} must be {rule}, not {val}", "options")
    ids = set()
    for i, o in enumerate(prob.objects):
        w = f"objects[{i}] ({o.id})"
        if not o.id or o.id == FLOOR:
            raise ProblemError(INVALID_REQUEST, "object id empty or reserved ('floor')", w)
        if o.id in ids:
            raise ProblemError(INVALID_REQUEST, f"duplicate object id {o.id!r}", w)
        ids.add(o.id)
        _finite(o.position, 3, w + ".position")
        q = _finite(o.quat_xyzw, 4, w + ".quat_xyzw")
        if abs(np.linalg.norm(q) - 1.0) > 1e-3:
            raise ProblemError(INVALID_REQUEST, "quaternion is not unit norm", w)
        if o.movable and not (o.mass > 0):
            raise ProblemError(INVALID_REQUEST, "movable object needs a positive mass", w)
        if np.linalg.norm(np.asarray(o.com, float)) > 1e-6:
            raise ProblemError(INVALID_REQUEST, "object frame must be at its centre of mass", w)
        if not o.primitives:
            raise ProblemError(INVALID_REQUEST, "object has no primitives", w)
        for p in o.primitives:
            he = p.half_extents()
            if not np.all(np.isfinite(he)) or np.any(he <= 0):
                raise ProblemError(INVALID_REQUEST, f"bad primitive size {p.size}", w)

    def check_obj(oid, where, allow_floor=True):
        if oid == FLOOR and allow_floor:
            return
        if oid not in ids:
            raise ProblemError(UNKNOWN_OBJECT, f"unknown object id {oid!r}", where)

    if prob.initial_configuration is None:
        raise ProblemError(INVALID_REQUEST, "initial configuration missing", "initial_configuration")
    x0 = _finite(prob.initial_configuration, 35, "initial_configuration")
    if not prob.phases:
        raise ProblemError(INVALID_REQUEST, "contact schedule has no phases", "phases")
    if abs(prob.phases[0].start) > 1e-9:
        raise ProblemError(INVALID_REQUEST, "first phase must start at t=0", "phases[0]")
    for i, ph in enumerate(prob.phases):
        w = f"phases[{i}]"
        _finite([ph.start, ph.end], 2, w + ".start/end")
        if ph.end - ph.start < 0.05:
            raise ProblemError(INVALID_REQUEST, f"phase too short or reversed ({ph.start}..{ph.end})", w)
        if i > 0:
            prev = prob.phases[i - 1].end
            if ph.start < prev - 1e-9:
                raise ProblemError(INVALID_REQUEST, f"phase overlaps the previous one ({ph.start} < {prev})", w)
            if ph.start > prev + 1e-9:
                raise ProblemError(INVALID_REQUEST, f"gap in the schedule ({prev} .. {ph.start})", w)
        if ph.phase_type not in (STANCE, WALKING):
            raise ProblemError(INVALID_REQUEST, f"phase type {ph.phase_type!r}", w)
        if not any(f in ph.contacts for f in FEET):
            raise ProblemError(INVALID_REQUEST, "no foot in contact (flight phases are not supported)", w)
        for limb, c in ph.contacts.items():
            if limb not in LIMBS:
                raise ProblemError(INVALID_REQUEST, f"unknown limb {limb!r}", w)
            check_obj(c.object_id, f"{w}.contacts[{limb}]")
            if c.position is not None:
                _finite(c.position, 3, f"{w}.contacts[{limb}].position")
            if c.heading is not None:
                _finite((c.heading,), 1, f"{w}.contacts[{limb}].heading")
                if limb not in FEET:
                    raise ProblemError(INVALID_REQUEST, "only a foot contact has a heading", f"{w}.contacts[{limb}]")
            n = _finite(c.normal, 3, f"{w}.contacts[{limb}].normal")
            if np.linalg.norm(n) < 1e-6:
                raise ProblemError(INVALID_REQUEST, "zero contact normal", f"{w}.contacts[{limb}]")
            if limb in FEET:
                if c.object_id != FLOOR and c.object_id in ph.objects:
                    raise ProblemError(INVALID_REQUEST, "feet may only stand on fixed surfaces",
                                       f"{w}.contacts[{limb}]")
                if abs(n[2] / np.linalg.norm(n)) < 0.99:
                    raise ProblemError(INVALID_REQUEST, "foot contact surface must be perpendicular "
                                       "to gravity", f"{w}.contacts[{limb}]")
            if limb in HANDS and c.position is None:
                raise ProblemError(INVALID_REQUEST, "hand contact needs a position",
                                   f"{w}.contacts[{limb}]")
        for oid, mo in ph.objects.items():
            check_obj(oid, f"{w}.objects", allow_floor=False)
            if not prob.object(oid).movable:
                raise ProblemError(INVALID_REQUEST, f"object {oid!r} is not movable", f"{w}.objects")
            if mo.mode not in OBJECT_MODES:
                raise ProblemError(INVALID_REQUEST, f"unknown object mode {mo.mode!r}", f"{w}.objects")
            if mo.mode in ("supported", "rolling"):
                check_obj(mo.support, f"{w}.objects[{oid}].support")
            if mo.mode == "attached":
                check_obj(mo.attached_to, f"{w}.objects[{oid}].attached_to", allow_floor=False)
                if mo.attached_to not in ph.objects:
                    raise ProblemError(INVALID_REQUEST, "attached to an object that does not move",
                                       f"{w}.objects[{oid}]")
    nj = 29
    subtasks = {ph.subtask_index for ph in prob.phases}
    for i, kf in enumerate(prob.keyframes):
        w = f"keyframes[{i}]"
        j = np.asarray(kf.joints, float).reshape(-1)
        if j.size != nj:
            raise ProblemError(INVALID_REQUEST, f"expected {nj} joint values, got {j.size}", w + ".joints")
        _finite(j, nj, w + ".joints")
        _finite(kf.base_position, 3, w + ".base_position")
        q = _finite(kf.base_quat_xyzw, 4, w + ".base_quat_xyzw")
        if abs(np.linalg.norm(q) - 1.0) > 1e-3:
            raise ProblemError(INVALID_REQUEST, "quaternion is not unit norm", w)
        if kf.subtask_index not in subtasks:
            raise ProblemError(INVALID_REQUEST, f"subtask {kf.subtask_index} not in the schedule", w)
        for c in kf.contacts:
            check_obj(c.object_id, f"{w}.contacts[{c.limb}]")
            if c.limb not in LIMBS:
                raise ProblemError(INVALID_REQUEST, f"unknown limb {c.limb!r}", w)
            _finite(c.position, 3, f"{w}.contacts[{c.limb}].position")
        if kf.reference_object_id:
            check_obj(kf.reference_object_id, w + ".reference_object_id")
        if kf.desired_foot_xy is not None:
            _finite(kf.desired_foot_xy, 2, w + ".desired_foot_xy")
        t = prob.keyframe_time(kf)
        if not (-1e-9 <= t <= prob.duration + 1e-9):
            raise ProblemError(INVALID_REQUEST, f"keyframe time {t} outside the schedule", w)
        if model is not None:
            lo, hi = model.q_lower - 1e-3, model.q_upper + 1e-3
            bad = np.where((j < lo) | (j > hi))[0]
            if bad.size:
                names = [model.joint_names[b] for b in bad[:3]]
                raise ProblemError(INVALID_REQUEST, f"joint values outside limits: {names}", w + ".joints")
    for i, g in enumerate(prob.placement_goals):
        w = f"placement_goals[{i}] ({g.object_id})"
        check_obj(g.object_id, w, allow_floor=False)
        if not prob.object(g.object_id).movable:
            raise ProblemError(INVALID_REQUEST, "placement goal for a fixed object", w)
        p = _finite(g.position, 3, w + ".position")
        _finite([g.yaw], 1, w + ".yaw")
        for k, (lo, hi) in enumerate(WORKSPACE):
            if not lo <= p[k] <= hi:
                raise ProblemError(INVALID_REQUEST, f"placement {p.tolist()} outside the workspace", w)
        # reachable: near some keyframe base or planned foot position (carrying/pushing reach)
        anchors = [np.asarray(kf.base_position, float) for kf in prob.keyframes]
        anchors.append(x0[:3])
        for ph in prob.phases:
            for limb, c in ph.contacts.items():
                if limb in FEET and c.position is not None:
                    anchors.append(np.asarray(c.position, float) + np.array([0, 0, 0.75]))
        dxy = min(np.linalg.norm(p[:2] - a[:2]) for a in anchors)
        dz = min(p[2] - (a[2] - 0.8) for a in anchors)
        if dxy > REACH_XY or dz > REACH_Z:
            raise ProblemError(INVALID_REQUEST, f"placement unreachable: {dxy:.2f} m from the nearest "
                               f"planned robot position (reach {REACH_XY} m)", w)
    if model is not None:
        bad = np.where((x0[6:] < model.q_lower - 1e-3) | (x0[6:] > model.q_upper + 1e-3))[0]
        if bad.size:
            raise ProblemError(INVALID_REQUEST, "initial joints outside limits", "initial_configuration")
