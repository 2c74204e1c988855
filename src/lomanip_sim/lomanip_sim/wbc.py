"""Whole-body controller: task-space inverse dynamics QP that tracks a whole-body trajectory.

Why: the plan must be carried out by joint torques under physics (friction contacts, no weld, no
qpos writes), so the controller solves, every physics step (500 Hz at the 2 ms timestep), one QP
over the G1's floating-base dynamics taken from the MuJoCo model itself:

    variables  x = [tau (29), qdd (35), f (3 per contact point)]
    minimise   sum_k w_k |A_k qdd - b_k|^2 + w_f |f_limb - f_plan|^2 + small regularisation
    subject to M qdd + h = S^T tau + J_c^T f          (35 rows: mass matrix qM, bias qfrc_bias - passive)
               |f_t1| + |f_t2| <= mu f_n, 0 <= f_n <= f_max      (MuJoCo's own pyramidal cone, mu 0.5 < 0.6)
               |tau| <= G1 rev 1.0 torque limits

Contacts follow the plan's contact schedule: a foot in contact is 4 sole-corner point forces with
a 6-D "no acceleration" task (weight 1e3, damped drift); a hand in contact is one point force in
the friction cone of the touched surface whose reference is the planned force, so the torques
carry the planned grasp/push forces as feed-forward while physics produces the real contact
(the hand collision boxes touching the object; nothing is welded). Tasks with PD feedback on the
plan's own kinematics (evaluated with MuJoCo on the planned configurations): CoM, pelvis
orientation and position, swing-foot pose, hand position and orientation, posture (all joints).
Where the dense plan sweeps a hand box into a static scene geom between its knots, the hand
reference is shifted round it (lomanip_sim.hand_detour); while shifted, that hand's position task
acts on its own arm only and a torso orientation task keeps the waist on the plan. A planned hand
contact whose object has left the hand (not touched for a while, grasp point out of the arm's
planned reach) is released until the plan's own release: no hand force, the arm back on the plan's
posture (``WbcGains.hand_release``).

Barrier rows on qdd (lomanip_sim.self_collision_guard, ``WbcGains.guard_rate``) keep the pelvis off
the hip-roll and hip-yaw links' meshes, a pair the TO bounds in joint space only, and each hand's box
off its own hip links and knee, which the TO's hand spheres under-cover (``WbcGains.guard_hands``);
rows on a hand's own arm keep its box off the movable objects while it has no contact near
(``WbcGains.guard_hand_objects``).

Named simplifications: the foot moment reference is not tracked (only the net planned foot force;
the QP distributes the corner forces); the CoM acceleration term J_dot v is neglected (site terms
use mj_jacDot); contact states come from the schedule, not from touch detection. The QP solver is
DAQP (dual active set, dense), solved from scratch each step (~0.45 ms of the ~1.5 ms step on this machine).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import daqp
import mujoco
import numpy as np

from . import frames
from .robot_model import (FOOT_BODIES, FOOT_CONTACT_POINTS, FOOT_SITES, FOOT_SOLE_OFFSET, G1_JOINT_NAMES,
                          HAND_BODIES, HAND_COLLISION_HALF_SIZE, HAND_SITES, PELVIS_BODY, TORSO_BODY)
from .contact_forces import LimbForceMeter
from .hand_approach import approach_lift, retreat_lift, smoothstep
from .hand_detour import Detour, HandBoxProbe, ObjectsAsObstacles, detour, movable_bodies, static_obstacle_geoms
from .self_collision_guard import HAND_LEG_PAIRS, HIP_PAIRS, GuardRow, SelfCollisionGuard
from .trajectory import FEET, HANDS, Trajectory
from .world import World

NJ = len(G1_JOINT_NAMES)
NV = NJ + 6
_SOLE_CORNERS = FOOT_CONTACT_POINTS - np.array([0.0, 0.0, 0.005])  # sphere centres -> sole (r = 5 mm)


class WbcError(RuntimeError):
    """The controller could not be set up for this model/trajectory."""


@dataclass
class WbcGains:
    """PD gains (1/s^2, 1/s), task weights and contact model of :class:`WholeBodyController`."""

    com_kp: float = 100.0
    com_kd: float = 20.0
    # CoM gains while the schedule has an object carried free (Phase.free_objects; 0 = com_kp / com_kd).
    # Why: in S1's carry the stiff CoM task drove the stance sole's centre of pressure to its toe edge
    # and the robot tipped forwards (session 48); softer gains on the whole plan lost 2-4 of the 64
    # demo pushes, which carry nothing free. With 30 / 11 in the carry only, session 45's S1 plan
    # gets past its carry (falls stepping onto the box at 13.96 s, against 6.42 s in the carry), and
    # S2 nominal's plan executes to task success in 5 of 7 model-error worlds against 4 (session 49)
    carry_com_kp: float = 30.0
    carry_com_kd: float = 11.0
    base_kp: float = 100.0  # pelvis orientation and position
    base_kd: float = 20.0
    foot_kp: float = 400.0
    foot_kd: float = 40.0
    swing_blend_time: float = 0.15  # s: a swing foot's target blends from where it lifted off into the plan
    # a swing foot lands where the capture point needs it: its target moves by this much per m of
    # capture-point error (0: off), faded in over the swing, at most step_adjust_max. The push's
    # remaining falls were sideways, in single stances, with the capture point leaving the stance
    # sole. Demo-push plans executed (docs/execution.md, session 11), of 12 (8 + 4) and of 8 plans
    # held out from the tuning: gain 0 9/12 and 6/8, 0.2 9/12, 0.3 11/12 and 7/8, 0.4 and 0.5
    # 10/12 and 7/8, 1.0 6/12 (with at most 0.05 m). Session 29: S2's carry runs the CoM 10-13 cm
    # off its plan in a single stance, past what 0.05 m catches; with 0.45 and 0.12 m it recovers
    # and the whole S2 plan executes to task success (0.3 / 0.05: falls at 6.8 s; 0.3 / 0.12: 6.9 s;
    # 0.6 / 0.12: 13.7 s), and the four bench_push plans still succeed (docs/execution.md)
    step_adjust_gain: float = 0.45
    step_adjust_max: float = 0.12  # m
    # A swing foot that lands on a movable object (S1's step onto the box) follows where that object
    # actually is: its target shifts by the planned landing point's displacement on the object
    # (actual pose against planned, yaw included), faded in over the swing's first half. Why: set
    # down 5 cm nearer than planned (the box 3.0 kg world), S1's rising right foot struck the box's
    # edge, pushed it 4 cm further and landed 9 cm off its centre; the foot slid off with the box
    # and the robot fell at 14.8 s. With it that run still falls (15.0 s: the body, planned for
    # the box's planned place, meets the moved box); S1's four other worlds succeed either way, and
    # no other plan steps onto an object (docs/execution.md, session 51)
    foot_follows_object: bool = True
    contact_kd: float = 20.0  # damping of a contact foot's drift velocity
    hand_kp: float = 400.0  # stiff near contacts: a lagging hand catches on the table edge (case_lift_box)
    hand_kd: float = 40.0
    # away from contacts the hands track as stiffly as near them: with soft free hands (kp 150,
    # weight 30) S1's arms lagged 7-16 cm in the first steps and the pelvis 5-8 cm with them
    free_hand_kp: float = 400.0
    free_hand_kd: float = 40.0
    # weight of a free hand's task (the arm's joints only, below). Was 300: in S2 nominal's walk to the
    # handle the reaching hands, lagging 13-16 cm, drove both soles' centres of pressure to the toes and
    # the robot fell at 11.4 s; at 30 that plan executes to task success (4 of 7 model-error worlds,
    # against none) and the demo push's 64 plan-and-world cases give 60 against 59 (session 49)
    w_free_hand: float = 30.0
    # away from contacts (outside ``hand_stiff_window``) a hand tracks the plan's hand carried with the
    # actual torso, with its own arm's joints only: a world-frame hand reference pulls the whole body
    # towards the plan's hand whenever the body lags its plan. In the demo push's approach walk the
    # free hand tasks (with the posture task) turned the CoM task's +30 N forward into -62 N on the
    # feet (the CoM task's weight hardly mattered), the CoM fell 19 cm/s behind and the robot fell
    free_hand_body_frame: bool = True
    w_free_hand_ori: float = 2.0
    hand_stiff_window: float = 0.6  # s before a hand contact starts (and after it ends) the stiff gains apply
    posture_kp: float = 100.0
    posture_kd: float = 20.0
    # a stance sole's zero acceleration, nearly a hard constraint: at 1e3 the QP traded it for the
    # other tasks at the end of a step, the heel lifted and the foot spun on its toes (the demo push,
    # docs/execution.md session 10: 2 of 4 plans executed at 1e3, 1 at 1e4, 3 at 1e5)
    w_contact: float = 1e5
    w_com: float = 100.0
    # pelvis (and, while the hands act on their arms only, torso) orientation; with the posture task
    # at 0.1: 50 executed 3 of 4 of the demo push's layouts, 20 or 10 all 4 (tools/bench_push.py)
    w_base_ori: float = 20.0
    w_base_pos: float = 50.0  # 5 let the pelvis drift 5-8 cm sideways over S1's first two steps
    w_swing: float = 200.0
    w_hand: float = 300.0
    w_hand_ori: float = 10.0
    # while a hand is in contact its orientation task is nearly off: the object's face sets the palm's
    # orientation, and tracking the planned one stiffly (10) twisted S1's box in the grasp whenever
    # its pose differed from the plan (box 0.3 rad, wrists 1.2 rad off, fell at 3.4 s, at the lift)
    w_hand_ori_contact: float = 0.1
    # per joint; a regulariser below the CoM, pelvis and hand tasks. At 1 the legs' posture (with the
    # plan's pelvis) fought the CoM task in every single stance of the demo push (the CoM task's
    # weight hardly changed the feet's forces); 0.03 with no torso task let the waist fold (falls at
    # 1.1 s); 0.1 with the torso task: 9 of 12 push plans executed (docs/execution.md, session 11).
    # At 1 on the arms only (the elbows run 0.1-0.18 rad off the plan at 0.1): 1 of 6
    w_posture: float = 0.1
    # centroidal angular momentum about the CoM towards the plan's (Trajectory.angular_momentum,
    # the TO's momentum interpolated between knots). Why: the dense joint motion
    # between knots can carry angular momentum the plan's wrenches do not (S1's lift, docs/to.md
    # session 19); this task lets the QP give up that part of the posture and hand tracking
    # instead of the balance. 0 = off, or when the trajectory has no momentum. Off by default: on
    # today's plans it did harm (demo pushes 1 of 4 executed against 3 of 4; docs/execution.md, session 20)
    w_angular_momentum: float = 0.0
    angular_momentum_kd: float = 10.0  # 1/s
    w_force: float = 1e-3  # per N^2, towards the planned contact force
    # m: a hand in contact presses a face, not a point: the contact may also carry a moment about
    # the hand site of up to this times its normal force about each tangent (the centre of pressure
    # anywhere within +- this of the site on the face; the hand box reaches 6.6 / 5.3 cm from it),
    # and hand_torsion times it about the normal. The TO plans with the same patch (HAND_PATCH_HALF,
    # HAND_TORSION). Why: S1's lift squeezes the box with 45-65 N along the palm normal at the site,
    # 0.1 m ahead of the wrist-yaw axis; as a point force that is 4.5-6.5 N m on the 5 N m wrist
    # yaw, so the QP turned the wrists away and the box slipped out (docs/execution.md, session 21).
    # 0 = a point force at the site
    hand_patch_half: float = 0.03
    hand_torsion: float = 0.01  # m
    w_hand_moment: float = 1e-2  # per (N m)^2: the centre of pressure stays at the site unless needed
    reg_qdd: float = 1e-5
    reg_force: float = 1e-5
    reg_tau: float = 1e-6
    # Sole friction the QP assumes. The G1's sole contacts in MuJoCo are four 5 mm spheres per foot
    # with friction 0.6 and priority 1 (so 0.6 holds against any floor), condim 3, pyramidal cone:
    # per sphere |f_t1| + |f_t2| <= 0.6 f_n (a "diamond"). The QP used a square pyramid with
    # mu 0.7 (up to 0.99 f_n diagonally), so it could ask a stance sole for more shear and yaw
    # moment than the floor gives: in S1 the stance sole spun 0.4 rad at the second step and the
    # other one slid 10-16 cm in the squat. Now the same diamond, with 0.5 for margin; the scenarios'
    # elliptic cone (session 46, |f_t| <= 0.6 f_n) contains it as well.
    mu_foot: float = 0.5
    diamond_cone: bool = True  # False: the old square pyramid |f_t1|, |f_t2| <= mu f_n
    f_max: float = 1500.0  # N per point
    hold_recentre_time: float = 1.0  # s: after the plan ends, the CoM moves over the sole centres
    com_margin: float = 0.03  # m: CoM reference kept this far inside the contact soles' bounding box
    # s, time constant with which the clamp's shift follows a new support. The box of one sole is its
    # centre line across (6 cm wide less 2 x 3 cm), and plans walk with the CoM 5-9 cm beside the
    # stance sole, so at each lift-off the reference jumped by that much: case_one_step's stance
    # sole slid 1.7 cm (0 s) / 1.4 cm (0.1 s), pelvis error 5.3 / 4.2 cm, with the same 9 of 12
    # demo-push plans executed. (The clamp to the centre line is what executes them: to the sole's
    # edges 5 of 12, none across in a single stance 5 of 12; docs/execution.md, session 11)
    com_clamp_time: float = 0.1
    # The CoM reference follows where the stance feet really are: it shifts horizontally by the
    # stance soles' placement errors (measured minus planned), weighted by the plan's vertical force
    # on each averaged over the next ``feet_follow_lookahead`` s, so before a foot lifts the shift is
    # already on the one that will stand alone. Why: in S1's step onto the box the left foot stood
    # 3.6 cm outside its planned place; the plan's CoM over the planned sole was 3.6 cm inside the
    # real one, the clamp above moves the reference only after lift-off, and the centre of pressure
    # went to the sole's inner edge. Off by default (docs/execution.md, session 50): with it S1's two
    # plans of session 48/50 pass the carry in 10 of 10 model-error worlds (8 of 10 without) and then
    # fall in the step-up, but S2 nominal executes to success in 1 of 7 worlds (5 of 7 without).
    # Shifting the pelvis reference too made both scenarios fall in their carry. 0: off, 1: full shift
    feet_follow: float = 0.0
    feet_follow_lookahead: float = 0.2  # s
    # the same shift (as a fraction, like feet_follow) while a stance foot stands on an object of the
    # plan: a swing foot landing on one aims where it actually is (foot_follows_object), so there the
    # real foothold is off the plan's by the object's displacement, and the CoM must come with it.
    # Why: S1's box was set down 5 cm further than planned; the right foot landed on it 5 cm ahead of
    # its plan, the CoM stayed planned over the heel, and the robot fell stepping up; with the shift
    # both feet reach the box and it falls 0.9 s later, in the grab (docs/execution.md, session 54).
    # The S1 fixture's plan still executes to task success; S2 and the push never stand on an object
    feet_follow_on_objects: float = 1.0
    feet_follow_time: float = 0.05  # s, time constant of the shift (first order)
    # grasp force optimisation on a carried object held by two or more hands: the QP chooses the hands'
    # forces, their sum fixed to the net force fed forward (what the object's motion needs) and each
    # inside a friction pyramid of ``mu_grasp`` about its face's normal (at least ``grasp_min_normal``
    # N into it), drawn to the fed-forward force (scaled squeeze) with ``w_grasp_force`` per N^2.
    # Why: fed forward as a fixed force, S2's doubled squeeze (68 N a hand) drove both shoulders and
    # wrists to their torque limits the moment the box left the table; the robot sagged 5 cm, unloaded
    # a foot and lost the box (docs/execution.md, session 36). The QP can squeeze less where the
    # torques run out, never less than friction needs. With it S2's nominal plan executes to task
    # success (without it the robot falls at the lift)
    grasp_force_in_qp: bool = True
    mu_grasp: float = 0.5  # the rubber hands' friction is 1.0: a margin of 2
    grasp_min_normal: float = 5.0  # N
    w_grasp_force: float = 1e-2  # per N^2 (1e-3 and 1e-4: S2 nominal fell after the set-down; docs/execution.md, session 36)
    # the grasp pyramids (and patch moment rows) about the face's normal on the object's ACTUAL pose
    # (the planned normal turned by the actual-vs-planned rotation) instead of the planned one. In
    # S1's first carrying step the box turned 10-20 degrees from its plan; about the planned normals
    # the QP asked 140 N up of one hand and 155 N down of the other against 40-80 N of real normal
    # force, and the box rolled to 48 degrees. With this the box stays within 20 degrees through that
    # step, but the QP then lets both squeezes drop to 10-18 N (a rolled box can rest on the lower
    # hand) and the box is lost in the next step: S1 falls earlier (5.0 against 13.9 s on the plan with
    # cop_margin_front 0.04; 5.6 against 6.4 s on the fixture's plan), S2 nominal succeeds either way.
    # A floor on each hand's normal force (0.5-1 x the plan's) made every plan fall earlier. Off
    # (docs/execution.md, session 38)
    grasp_normal_on_actual_object: bool = False
    # The moment the hands' forces and patch moments put on a carried object about its actual CoM is
    # drawn to I (kp e_R - kd w) + w x I w: what turns it towards its planned orientation
    # (``w_grasp_moment`` per (N m)^2; 0 = off). Why: with only the forces' sum fixed, the QP used
    # the hands' opposite shear forces as a free moment on the robot (a balance actuator); the box
    # can return that moment only by turning, so physics gave a different split and the box rolled
    # about the line between the hands: S2 nominal set it down on its side (tilt 90 degrees).
    # With 1000: upright (0 degrees) and task success in 7 of 7 model errors of S2 nominal's plan
    # (box mass 2.0 / 3.0 kg, trolley 6 / 10 kg, wheel resistance x0.5 / x2; without: 5 of 7, the
    # box-mass errors fall); S1 and S2 at 5 kg fall either way (docs/execution.md, session 39)
    w_grasp_moment: float = 1000.0
    grasp_orientation_kp: float = 100.0  # 1/s^2
    grasp_orientation_kd: float = 20.0  # 1/s
    # s, see WholeBodyController._hand_offsets. Was 0.3: S1's plan brings the right hand (a point in
    # the TO) 2-4 cm over the box's front corner 0.6 s before the grasp, the 13 x 7 x 11 cm hand box
    # caught on that edge and the arm pushed the robot backwards (fell at 2.6 s)
    hand_offset_ramp: float = 0.8
    hand_release_ramp: float = 0.3  # s over which the offset goes after a hand contact ends
    # the offset's ramps (and the approach clearance's) are smoothsteps, not linear: a linear ramp
    # steps the hand reference velocity where it starts, the acceleration reference spikes and the
    # hand tasks (full Jacobian) drag the whole body with it; in the push of make demo both hands'
    # offsets (6-7 cm along (-0.8, 0, 0.6)) started at 1.8 s and the QP took the CoM back at -2.5
    # m/s^2 for 30 ms, 3.3 cm in front of the heels: the robot fell backwards at 2.5 s
    hand_offset_smooth: bool = True
    hand_squeeze: float = -0.005  # m: hand target this far inside the surface (negative = into the object)
    # m, the same for a hand on an object the plan lifts (a grasp that carries it). Why: at 5 mm the
    # hands' real squeeze on S1's 2.5 kg box was 15-35 N a side, the box slid 10 cm down between them
    # over 1.5 s of the carry and was lost at 6.3 s (the same plan executes in the box 2.0 kg world);
    # with 2.5 cm S1's plan executes to task success in 4 of its 5 worlds (1.0 cm: 0 of 1, 1.5 cm:
    # 2 of 5, 2.0 cm: 3 of 5); S2's in 4 of 7 as at 5 mm. Only on lifted objects: 2.5 cm on every
    # contact took the demo's push from 60 to 43 of 64 (S2: 5 of 7; docs/execution.md, session 51)
    hand_squeeze_lifted: float = -0.025
    # the hand offset subtracts the plan's own distance of the hand site from the surface, read off
    # the plan's contact points where it gives them (Trajectory.points), so a plan whose hand already
    # stands off the surface (lomanip_to Options.hand_standoff) is not pushed out twice, and one whose
    # site lies inside it (the TO's hand point is on the wrist axis, the site 1.2 cm towards the palm)
    # is pushed out by that much more. False: the offset is the hand box's support distance alone
    hand_offset_plan_gap: bool = True
    hand_clearance: float = 0.02  # m, extra distance from the surface while approaching a contact
    hand_engage_error: float = 0.06  # m: planned hand force is applied once the hand got this close
    # s: the planned hand force is fed forward only while the hand box has touched its object within
    # this time (MuJoCo contacts; bridges the few-ms gaps of a sliding grasp; a grasp engaged at its
    # target before touching gets this long to touch). Without it, once S1's box (the knee-sphere
    # plan) slipped out of the hands in the lift at 3.7 s, the QP kept assuming the box's squeeze and
    # weight on the hands through the carrying steps: the hands clashed and the robot fell at 5.3 s
    # (6.2 s with it). 0 = the old latch (force from engagement to the end of the contact phase)
    hand_lost_time: float = 0.1
    # the hand position reference is shifted round static scene geoms (tables, shelves) where the
    # dense plan sweeps the hand box into them between knots (lomanip_sim.hand_detour); S2's right
    # hand went 96 mm into the table top at 1.9 s, wedged under it and the robot fell at 2.5 s
    hand_detour: bool = True
    # m, clearance kept by a shifted stretch. 0.04 since session 55: S1 from prompts (its plan's hand
    # boxes 4-8 cm into the shelf between knots in the grab) fell backwards lifting the basket at
    # 22.70 s with 0.02 and executes to task success with 0.04; the S1 and S2 fixtures' plans and the
    # push's 8 replays keep their task success (docs/execution.md, session 55)
    hand_detour_margin: float = 0.04
    hand_detour_pre_contact: float = 0.2  # s, a shift is gone this long before the hand's next contact
    # while shifted, the hand position task drives only its own arm's joints and the torso tracks the
    # plan's orientation: with the full Jacobian the hand tasks (weight 300) leant the torso back 0.3
    # rad to lift the hands, the CoM fell 7 cm behind the plan and S2 fell backwards at 2.3 s
    hand_detour_arm_only: bool = True
    # a hand's contact normal turns with its object's planned orientation (the phase gives it at the
    # start, the TO turns it with the object): S2's box yaws -1.6 rad in the carry and the fixed normal
    # put the hand offsets (3-5 cm) along the faces instead of out of them
    hand_normal_follows_object: bool = True
    # before a hand contact the reference is lifted along the contact normal where the hand box would
    # go into the scene (lomanip_sim.hand_approach): the push's plan brings both hands up through the
    # trolley's handle bar (up to 62 mm) to grasp it from behind and above
    hand_approach: bool = True
    hand_approach_margin: float = 0.01  # m, kept from the scene by the lifted approach
    # s before the contact's start from which the hand box is checked. bench_push's base plan brings
    # both free hands within 0-1 cm of the handle (reference boxes up to 7 mm inside) 1.0-1.3 s before
    # their contact; with tracking errors the left hand catches the bar at 1.7 s and draws the trolley
    # 4 cm back, and that plan fails in 5 of 7 perturbed worlds. 1.5 s (margin 2 cm) saves base
    # (6 of 7) but makes near_right fall in all 7 (its lifted right hand lags 8-15 cm and strikes),
    # 1.2 s the same: 38 and 37 of 56 cases against 41 (docs/execution.md, session 30). Kept at 0.8
    hand_approach_window: float = 0.8
    # a free hand's reference that goes into a movable object (at its planned pose) before the
    # approach window of its first contact is shifted round it as hand_detour shifts round static
    # geoms: bench_push's base plan brought both hands within 0-1 cm of the handle a second before
    # the grasp, the left caught the bar and drew the trolley back (2 of 7 worlds). With it, 49 of 56
    # push cases against 41; off after the first contact's window, where it broke plans (30 of 56)
    hand_detour_movable: bool = True
    # the lift is tilted towards up by this much (normal + k up, normalised) on faces that look up:
    # along the handle's normal (-0.8, 0, 0.6) the lift pulled the left hand back into the torso
    hand_approach_up: float = 1.0
    hand_approach_spread: float = 0.4  # s, half-width of the smooth kernel that spreads each sample's lift
    hand_approach_taper: float = 0.4  # s over which the lift goes to zero (0.1 s: 230 N landing on the bar)
    hand_approach_post: float = 0.2  # s after the contact start at which the lift is gone (force still ~0)
    # after a hand contact ends the reference is lifted the same way, in reverse (hand_approach.retreat_lift):
    # the push's plan lowers both hands 20 cm through the trolley's handle bar once it lets go; the
    # hand boxes stayed on the bar with 10-35 N for 1.8 s and the robot fell backwards (make demo)
    hand_retreat: bool = True
    # s after the contact's end up to which the hand box is checked, at most up to the approach
    # window of the hand's next contact: with 0.8 the demo push's plan lowered the right hand onto the
    # bar 0.1 s after the window, at 5.7 s, and shoved the trolley from 6 cm behind its plan to 20 cm
    # ahead (with 1.5: the same at 6.4 s; with 2.5 it ends 4.6 cm behind: session 33)
    hand_retreat_window: float = 3.0
    # where no retreat lift along the released contact's normal is clear: the lift whose clearance
    # falls least short (0 included), not the largest. Why: letting go of the box on the trolley's
    # deck, S2's hands found no clear lift along the box's faces, the full 25 cm drove the right
    # wrist into the trolley's post (44-115 N at 7.96-8.04 s) and rolled the trolley 9.6 cm back;
    # the push then caught up and the trolley ended 12 cm past its goal (docs/execution.md, session 50).
    # The demo push's 8 saved layouts in 8 worlds execute as before (60 of 64)
    hand_retreat_least_bad: bool = True
    hand_retreat_rise: float = 0.3  # s from the release over which the lift rises (from 0: none before it)
    # N: the release is the contact's end or, earlier, the last time the plan's hand force is above
    # this (the demo push's plan stops pushing at 4.2 s, 0.6 s before its contact ends, and lowers
    # the hands through the bar from 4.6 s: lifted from the contact's end it still fell, at 6.76 s)
    hand_retreat_force: float = 1.0
    # m, kept from the scene at its planned pose: a pushed object lags its plan by 1-3 cm, and with
    # 0.03 the demo push's hands still caught the bar (2 of 4 pushes that fell with the bar under the
    # hands no longer fall at 0.05: docs/execution.md, session 24)
    hand_retreat_margin: float = 0.05
    # after a contact with an object pushed on the floor, a free hand's reference rides on the
    # object's actual pose as long as the planned hand box is near the planned object (weight 1
    # within hand_registered_near of it, 0 beyond hand_registered_far): the plan's hand moves
    # relative to where it planned the object, and a trolley that lagged its plan by 4 cm took the
    # plan's lowered right hand on its bar 1 s after the release and rolled 9 cm too far (session 25)
    hand_registered_after_release: bool = True
    hand_registered_near: float = 0.05
    hand_registered_far: float = 0.15
    # ... but only the part of the object's displacement that moves the hand out of the released
    # contact's face (along its outward normal, taken in the floor plane unless the face looks up),
    # never into it: a trolley ahead of its plan drew the released hands after it, they touched it
    # and pushed it on, +16-22 cm (make demo, session 32)
    hand_registered_outward_only: bool = True
    # while a hand's grasp offset is active (approach ramp, contact, release) its position task acts
    # on its own arm only and the torso tracks the plan's (as in a detour): with the full Jacobian
    # the offsets (6-7 cm back and up, off the planned posture) pulled the whole body back; the push
    # of make demo lost its CoM 3 cm in front of the heels and fell backwards at 2.5 s
    hand_arm_only_near_contact: bool = True
    # in a contact the hand position reference rides on the object's actual pose (the plan's grasp
    # point carried from the planned to the actual object frame): in the push the trolley ran 6 cm
    # behind the plan at 4.6 s, the stiff hands chased the planned handle and pressed 430 N onto
    # the bar (plan 34 N), the robot leant on the rolling trolley and fell forwards at 6.0 s
    hand_follows_object: bool = True
    # a planned hand contact whose object has left the hand is released by the controller until the
    # plan's own release (WholeBodyController._release_hands): no contact force variable (nothing fed
    # forward, the feet carry everything), the hand stops chasing the object. Released when the hand
    # has touched the object in this contact, has not touched it for ``hand_release_time`` s AND the
    # grasp point on the actual object is more than ``hand_release_reach`` from the plan's hand carried
    # with the actual torso (where the arm would be without chasing; a hand that only bounces off a
    # grasp that is still there is not released). The push of make demo pushes the trolley with one
    # impulse and lets it coast; executed, it ran 3-5 cm ahead of the plan and left the hands at
    # ~3.6 s while the plan kept them on it to 4.8 s; the hands followed it (hand_follows_object),
    # the robot stood on one foot in a planned double stance and, after 160 s of standing, the
    # pelvis ran 20 cm off the plan (the graph run fell at 5.58 s)
    hand_release: bool = True
    hand_release_time: float = 0.2  # s without touching (> hand_lost_time: bridges a sliding grasp's gaps)
    # m: 2-4 cm while the push's hands are still on the handle (body and trolley errors); the half
    # thickness of the hand box is 3.3 cm
    hand_release_reach: float = 0.05
    # a released arm's joints track the plan's posture with this weight while its hand position and
    # orientation tasks fade out (their reference moving to the plan's hand carried with the torso);
    # 0: the hand tasks stay on, on that reference (push after 160 s of standing: pelvis 13.3 vs 12.8
    # cm, joints 1.13 vs 0.92 rad: the orientation task, off in the contact, turned the elbow 1 rad)
    hand_release_posture: float = 100.0
    hand_release_blend: float = 0.3  # s, smoothstep from the contact's tasks to the released ones (and back)
    # the hands' net force on a lifted object (planned this high above its initial height) is fed
    # forward as what the object's planned motion needs, m (a + g), split equally between the hands
    # that hold it; the plan's squeeze (each hand's force minus the hands' mean) is kept. The TO's
    # forces act over a whole knot interval (explicit Euler), and where an object leaves its support
    # the last support knot's force lifts it: S1's box rises 14 cm (0 -> 0.7 m/s) over 3.0-3.2 s
    # on 71.5 N from the floor while the planned hands push it down with 38 N. Fed forward as
    # planned, the hands pressed the box down as it was to rise, it stayed on the floor (lost at
    # 3.1 s) and the robot fell at 4.24 s; with this, the box is carried to 3.56 s (fell at 5.58 s)
    hand_force_from_object_motion: bool = True
    object_lift_height: float = 0.01  # m
    # the plan's squeeze on a lifted object (each hand's force minus the hands' mean) is fed forward
    # times this; the net force on the object is unchanged. The TO plans each hand at 0.57 of the
    # friction cone's edge, and under MuJoCo's soft contacts S2's box crept down between the hands
    # while the robot walked with it, until they lost it at 4.9 s; with 2 it stayed in the hands
    # (docs/execution.md, session 29). 1 feeds the plan's squeeze forward as it is
    grasp_squeeze_scale: float = 2.0
    # on an object pushed along the floor (one the hands follow), the hand's reference along the
    # contact normal is an admittance: it moves out of the object while the measured normal force
    # exceeds the desired one and into it while it is below (rate in m/s per N, depth bounded).
    # The desired force is the plan's, less push_object_gain times how far the object is ahead of
    # its plan along the push (more where it lags), between push_min_force and the plan's +
    # push_max_extra. Why: a position-controlled hand 5 mm inside a freely rolling trolley drives it
    # (the reference rides on the trolley): in the graph's push the right hand pushed 16 N where
    # 1-9 N were planned, the trolley ran 9 cm ahead before the planned push began, the hands chased
    # it and the robot fell at 3.7 s
    hand_push_admittance: bool = True
    hand_admittance_rate: float = 0.005
    hand_admittance_out: float = 0.05  # m, most the reference backs out of the surface
    # m, most it goes further in. 0.03 until session 47: on the trolley's oblique handle face (normal
    # about (-0.55, 0, 0.84)) 3 cm in is 2.5 cm down; in a make demo push whose trolley lagged 8 cm the
    # wrists pressed the handle 40-90 N down and their friction pushed the robot 30 N sideways until it
    # fell (docs/execution.md, session 47)
    hand_admittance_in: float = 0.01
    push_object_gain: float = 200.0  # N/m
    # N per m/s of the object's speed over its plan's along the push, taken off the desired force (0:
    # off): the catch-up after a lag otherwise ends with the trolley faster than planned, and it rolls
    # on past its goal. Session 47, bench_push's 8 fresh layouts and 3 make demo plans x 8 worlds (88
    # cases): with hand_admittance_in 0.01 80 succeed, 2 fall; 0.01 alone 77 / 4; this alone 66 / 7;
    # neither (the defaults before) 72 / 6
    push_object_damping: float = 60.0
    push_min_force: float = 2.0  # N: a hand keeps touching an object that runs ahead
    push_max_extra: float = 40.0  # N over the plan's normal force
    # on a pushed object, a touching hand that is off its contact point along the surface (farther
    # than hand_backoff_free from the plan's point carried with the object) has its reference backed
    # out along the normal by hand_tangential_backoff times the excess, at most hand_backoff_max
    # (0: off). Why: in session 26's make demo push the right hand reached the bar 4.6 cm to the
    # side of its plan while the plan swept it 12 cm sideways in 0.2 s, struck it with 39 N where
    # 1-5 N were planned, and the trolley rolled 13 cm ahead (0.39 m of 0.25 m); backed off, that
    # plan pushes 0.25 m and 12 of 15 saved push plans succeed against 11, one falls against two
    hand_tangential_backoff: float = 1.0  # m per m
    hand_backoff_free: float = 0.02  # m
    hand_backoff_max: float = 0.05  # m
    # on a pushed object, a touching hand's force is fed forward as measured (the step before), not as
    # the plan's: the QP took the planned force along the plan's normal (-0.8, 0, 0.6) as given, but
    # the left hand box met the demo's handle bar from behind and below (contact normal (-0.97, 0,
    # -0.25)), the upward part the QP counted on was not there and the hand sagged 5 cm below its
    # reference, pushing the trolley 7 cm too far; measured, the hand stays within 1-2 cm and meets
    # the bar along (-0.71, 0, 0.70). 9 of 12 saved push plans executed to success against 8, two
    # falls either way (docs/execution.md, session 24)
    push_feedforward_measured: bool = True
    # barrier rows keeping the pelvis off the hip-roll and hip-yaw links' meshes
    # (lomanip_sim.self_collision_guard; rate in 1/s, 0 = off): rows for pairs nearer than
    # guard_activation (m), kept at least guard_min_distance (m) apart. Why: the plan's hip roll
    # sits 1-2 mm off the pelvis in deep squats, and S1's lift from prompts jammed the pelvis on the
    # right hip-roll link with 1.4 kN (docs/execution.md, session 54)
    guard_rate: float = 10.0
    guard_activation: float = 0.02
    guard_min_distance: float = 0.001
    # the guard also keeps each hand off its own hip links and knee (HAND_LEG_PAIRS): the TO's two
    # hand spheres leave the sim's hand box's edges out by up to 2.3 cm
    guard_hands: bool = True
    # the guard also keeps a free hand's box off each movable object (trolley, box, basket) until the
    # hand's next contact with anything starts, and from guard_object_release s after a contact ends.
    # Why: the approach references come within 1 cm of the object a second before the grasp, and a
    # hand lagging its reference by 2-5 cm struck the trolley's handle before the grasp (make demo,
    # session 59: the right hand at 1.92 s, 30 N; the trolley rolled 12 cm ahead of its plan)
    guard_hand_objects: bool = True
    guard_object_release: float = 0.3
    guard_object_min_distance: float = 0.003


@dataclass
class _Refs:
    """Task references on the trajectory grid, from MuJoCo kinematics of the planned states."""

    com: np.ndarray
    com_v: np.ndarray
    com_a: np.ndarray
    base_p: np.ndarray
    base_v: np.ndarray
    base_a: np.ndarray
    base_R: np.ndarray
    base_w: np.ndarray
    base_alpha: np.ndarray
    torso_R: np.ndarray | None = None  # (N,3,3)
    torso_p: np.ndarray | None = None  # (N,3) torso body origin
    torso_w: np.ndarray | None = None  # (N,3) world angular velocity
    site_p: dict = field(default_factory=dict)  # limb -> (N,3)
    site_R: dict = field(default_factory=dict)  # limb -> (N,3,3)
    site_v: dict = field(default_factory=dict)  # limb -> (N,6) linear, angular (world)
    site_a: dict = field(default_factory=dict)  # limb -> (N,6)
    qdd: np.ndarray | None = None
    angmom: np.ndarray | None = None  # (N,3) planned angular momentum about the CoM
    angmom_rate: np.ndarray | None = None  # (N,3)


_EYE3 = np.eye(3)
_ZERO3 = np.zeros(3)
_JOINT_ROWS = np.eye(NV)[6:]  # the posture task's Jacobian (qdd of the joints)
_DIAG_NV = np.diag_indices(NV)


_SUMMED: dict[int, np.ndarray] = {}


def _summed_points(n: int) -> np.ndarray:
    """S^T S for S = [I3 ... I3] (n blocks): the Hessian of |sum of n point forces|^2."""
    out = _SUMMED.get(n)
    if out is None:
        out = _SUMMED[n] = np.tile(_EYE3, (n, n))
    return out


def _point_jacobians(J: np.ndarray, r: np.ndarray) -> np.ndarray:
    """(n, 3, NV) linear Jacobians of points at offsets ``r`` (n, 3) from a site with Jacobian ``J``
    (6, NV): J_p - [r]x J_w, i.e. J_p + J_w x r column by column."""
    Jp, Jw = J[:3], J[3:]
    x, y, z = r[:, 0:1], r[:, 1:2], r[:, 2:3]
    out = np.empty((len(r), 3, J.shape[1]))
    out[:, 0] = Jp[0] + z * Jw[1] - y * Jw[2]
    out[:, 1] = Jp[1] + x * Jw[2] - z * Jw[0]
    out[:, 2] = Jp[2] + y * Jw[0] - x * Jw[1]
    return out


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _rot_error(R_des: np.ndarray, R: np.ndarray) -> np.ndarray:
    """World-frame rotation vector (small-angle) that takes R to R_des."""
    E = R_des @ R.T
    return 0.5 * np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]])


@dataclass
class WbcStatus:
    """What the last control step saw (for feedback, logs and tests)."""

    t_ref: float = 0.0
    base_position_error: float = 0.0
    joint_error_rms: float = 0.0
    joint_error_max: float = 0.0
    qp_ok: bool = True
    qp_failures: int = 0
    qp_iterations: int = 0
    contacts: tuple = ()


class WholeBodyController:
    """TSID QP tracking ``traj`` on the robot of ``world``; a TorqueController for Simulation."""

    def __init__(self, world: World, traj: Trajectory, gains: WbcGains | None = None):
        self.world, self.traj, self.g = world, traj, gains or WbcGains()
        m = self.model = world.model
        self.pelvis = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, PELVIS_BODY)
        self.torso = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, TORSO_BODY)
        self.bdof = int(m.jnt_dofadr[m.body_jntadr[self.pelvis]])
        self.bq = int(m.jnt_qposadr[m.body_jntadr[self.pelvis]])
        if not np.array_equal(world.joint_dof_adr, np.arange(self.bdof + 6, self.bdof + NV)):
            raise WbcError("the G1's joints must follow its free joint contiguously in qvel")
        self.dofs = slice(self.bdof, self.bdof + NV)
        self.sites = {"left_foot": FOOT_SITES["left"], "right_foot": FOOT_SITES["right"],
                      "left_hand": HAND_SITES["left"], "right_hand": HAND_SITES["right"]}  # fmt: skip
        self.site_id = {l: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, s) for l, s in self.sites.items()}
        if min(self.site_id.values()) < 0:
            raise WbcError("foot/hand sites missing from the model")
        foot_body = {"left_foot": FOOT_BODIES["left"], "right_foot": FOOT_BODIES["right"]}
        self.foot_body = {l: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, b) for l, b in foot_body.items()}
        self.limits = np.asarray(world.torque_limits, float)
        self.hand_geom = {l: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"{l}_collision") for l in HANDS}
        self._jp = np.zeros((3, m.nv))
        self._jr = np.zeros((3, m.nv))
        self._jdp = np.zeros((3, m.nv))
        self._jdr = np.zeros((3, m.nv))
        self._M = np.zeros((m.nv, m.nv))
        self._scratch = mujoco.MjData(m)
        self.detours: list[Detour] = []
        self._object_turn: dict[str, np.ndarray] = {}  # object -> (N,3,3) planned rotation since t = 0
        self._normals: dict = {}  # id(contact) -> (N,3) normals along the grid (_contact_normals)
        self._object_body: dict[str, tuple] = {}  # object -> (body id, CoM offset in the body frame)
        self._detoured = {l: np.zeros(traj.n, bool) for l in HANDS}
        self._registered: dict[str, list] = {}  # hand -> [(object, (N,) weight, (N,3) normal)] (_registration)
        #: hand -> shift (world, m) of its reference this step by hand_registered_after_release
        self.registered_shifts: dict[str, np.ndarray] = {}
        self._lifted: dict[str, bool] = {}  # object -> moved vertically by the plan (_lifted_in_plan)
        self._landings: dict = {}  # (foot, id(swing phase)) -> (object id, landing index) or None (_landing)
        self._arm_only = {l: np.zeros(traj.n, bool) for l in HANDS}  # hand position task on its own arm only
        self.approach_lifts: list[tuple[str, float, float]] = []  # (hand, contact start, largest lift in m)
        self.retreat_lifts: list[tuple[str, float, float]] = []  # (hand, contact end, largest lift in m)
        # columns of a hand's own arm (shoulder to wrist) in the QP's qdd (6 base dofs first)
        self._arm_cols = {l: np.array([6 + j for j, nm in enumerate(G1_JOINT_NAMES) if nm.startswith(l.split("_")[0])
                                       and any(k in nm for k in ("shoulder", "elbow", "wrist"))])
                          for l in HANDS}  # fmt: skip
        self.refs = self._precompute_refs()
        self._hand_stiff = {l: self._near_contact(l) for l in HANDS}
        self._object_net = self._object_net_forces() if self.g.hand_force_from_object_motion else {}
        self._pyramids: dict = {}
        self._vel6 = np.zeros(6)
        self._admittance_keys: dict = {}  # id(contact) -> (contact, its key in _admittance)
        #: (QP layout, daqp sense bits of its active inequalities) of the last step: at 500 Hz the
        #: active set hardly changes, and starting from it halves daqp's time
        self._qp_working_set: tuple | None = None
        self._object_root: dict[str, int] = {}  # object -> its root body (-1: not in the model)
        self._touch_key: tuple | None = None  # (data, time, ncon) of the scan in _hand_contact_roots
        self._touch_roots: dict[str, set] = {}
        self.t0 = 0.0
        self.status = WbcStatus()
        self.last_forces: dict[str, np.ndarray] = {}
        self.last_sole_forces: dict[str, np.ndarray] = {}  # stance foot -> (4, 3) the QP's corner forces (world)
        #: moment (world, N m) the QP put on each hand contact about its site (hand_patch_half)
        self.last_hand_moments: dict[str, np.ndarray] = {}
        self._last_tau = np.zeros(NJ)
        self.last_qdd = np.zeros(NV)  # the QP's accelerations (base 6, then the joints), last solved step
        self._engaged: dict = {}
        self._last_touch: dict = {}  # hand -> trajectory time its collision box last touched its object
        self._touched: dict = {}  # hand -> object it has touched in its current planned contact
        self.released: dict = {}  # hand -> (object, time released, time of the plan's own release or None)
        self.release_events: list[tuple[str, str, float, float]] = []  # (hand, object, time, grasp point distance)
        self._swing_start: dict = {}
        self._meter = LimbForceMeter(m)
        self.measured_forces = {l: np.zeros(3) for l in (*FEET, *HANDS)}  # on the robot, after the last step
        self._admittance: dict = {}  # hand -> [contact, normal shift (m)] while pushing a floor object
        self._push_force: dict = {}  # hand -> (normal, desired normal force on the robot) this step
        self._com_shift = np.zeros(2)  # the CoM reference's clamp shift (com_margin, com_clamp_time)
        self._feet_shift = np.zeros(2)  # the CoM reference's shift onto the real stance feet (feet_follow)
        self._feet_share = self._planned_feet_share()
        root = int(m.body_rootid[self.pelvis])
        self._robot_bodies = [b for b in range(1, m.nbody) if int(m.body_rootid[b]) == root and m.body_mass[b] > 0]
        self._angmom_prev: tuple[float, np.ndarray] | None = None  # (time, A_L) of the last step
        pairs = HIP_PAIRS + (HAND_LEG_PAIRS if self.g.guard_hands else ())
        self.guard = (SelfCollisionGuard(m, pairs, activation=self.g.guard_activation, rate=self.g.guard_rate,
                                         min_distance=self.g.guard_min_distance) if self.g.guard_rate > 0 else None)
        self.object_guard = None
        self._object_pairs: dict[str, list[tuple[str, str]]] = {}
        self._object_free = {}  # hand -> (N,) bool: its object rows are on at a sample (no contact near)
        objects = movable_bodies(m, root)
        if self.g.guard_rate > 0 and self.g.guard_hand_objects and objects:
            self.object_guard = SelfCollisionGuard(m, (), activation=self.g.guard_activation, rate=self.g.guard_rate,
                                                   min_distance=self.g.guard_object_min_distance)
            for limb in HANDS:
                body = HAND_BODIES[limb.split("_")[0]]
                self._object_pairs[limb] = [self.object_guard.guard_object(body, b) for b in objects]
                free = self._free_of_objects(limb)
                self._object_free[limb] = free & np.append(free[1:], free[-1])   # at a sample and the next
        self._hand_of_pair = {k: limb for limb, keys in self._object_pairs.items() for k in keys}
        self.guard_rows: list[GuardRow] = []  # the self-collision guard's active rows, last step

    # ---------------------------------------------------------------------------- references
    def _take_detour(self, limb: str, before: np.ndarray, shifted: np.ndarray, found: list[Detour]) -> np.ndarray:
        """Record a :func:`detour` of ``limb``'s reference: the shifted samples are tracked by the arm alone."""
        moved = np.any(np.abs(shifted - before) > 1e-9, axis=1)
        self._detoured[limb] |= moved
        self._arm_only[limb] |= moved
        self.detours.extend(found)
        return shifted

    def _precompute_refs(self) -> _Refs:
        tr, m, d = self.traj, self.model, self._scratch
        n = tr.n
        com, com_v = np.zeros((n, 3)), np.zeros((n, 3))
        base_R, base_w, torso_R, torso_w = np.zeros((n, 3, 3)), np.zeros((n, 3)), np.zeros((n, 3, 3)), np.zeros((n, 3))
        torso_p = np.zeros((n, 3))
        sp = {l: np.zeros((n, 3)) for l in self.sites}
        sR = {l: np.zeros((n, 3, 3)) for l in self.sites}
        sv = {l: np.zeros((n, 6)) for l in self.sites}
        jcom = np.zeros((3, m.nv))
        d.qpos[:] = self.world.stand_qpos
        for i in range(n):
            d.qpos[self.bq : self.bq + 7 + NJ] = tr.qpos(i)
            d.qvel[:] = 0.0
            d.qvel[self.dofs] = tr.qvel(i)
            mujoco.mj_kinematics(m, d)
            mujoco.mj_comPos(m, d)
            com[i] = d.subtree_com[self.pelvis]
            mujoco.mj_jacSubtreeCom(m, d, jcom, self.pelvis)
            com_v[i] = jcom @ d.qvel
            base_R[i] = d.xmat[self.pelvis].reshape(3, 3)
            torso_R[i] = d.xmat[self.torso].reshape(3, 3)
            torso_p[i] = d.xpos[self.torso]
            mujoco.mj_jacBody(m, d, self._jp, self._jr, self.torso)
            torso_w[i] = self._jr @ d.qvel
            base_w[i] = base_R[i] @ tr.qvel(i)[3:6]
            for l, sid in self.site_id.items():
                sp[l][i] = d.site_xpos[sid]
                sR[l][i] = d.site_xmat[sid].reshape(3, 3)
                mujoco.mj_jacSite(m, d, self._jp, self._jr, sid)
                sv[l][i, :3] = self._jp @ d.qvel
                sv[l][i, 3:] = self._jr @ d.qvel
        t = tr.t
        root = int(m.body_rootid[self.pelvis])
        static_geoms = static_obstacle_geoms(m, root)
        obstacles = static_geoms if self.g.hand_detour else []
        mov_bodies = movable_bodies(m, root)
        movable = self._movable_poses(mov_bodies) if obstacles or (self.g.hand_approach and mov_bodies) else {}
        for limb in HANDS:  # the plan's hand is a point on the surface; the sim's hand is a box
            off = self._hand_offsets(limb, sR[limb], sp[limb])
            sp[limb] = sp[limb] + off
            if self.g.hand_approach and movable and self.hand_geom[limb] >= 0:
                probe = HandBoxProbe(m, self.hand_geom[limb], self.site_id[limb], static_geoms, movable)
                starts = self._contact_starts(limb)
                for start, c in starts:
                    normals = self._lift_normals(self._contact_normals(c))
                    lift = approach_lift(t, sp[limb], sR[limb], normals, start, probe, window=self.g.hand_approach_window,
                                         margin=self.g.hand_approach_margin, spread=self.g.hand_approach_spread,
                                         taper=self.g.hand_approach_taper, post=self.g.hand_approach_post)  # fmt: skip
                    sp[limb] = sp[limb] + lift[:, None] * normals
                    self.approach_lifts.append((limb, start, float(lift.max())))
                if self.g.hand_detour_movable and starts:  # before the first contact's approach window only
                    guard = t >= starts[0][0] - self.g.hand_approach_window
                    sp[limb] = self._take_detour(limb, sp[limb], *detour(limb, t, sp[limb], sR[limb], guard,
                                                 ObjectsAsObstacles(probe), self.g.hand_detour_margin, 0.0))
                if self.g.hand_retreat:
                    for end, c_end, c in self._contact_ends(limb):
                        normals = self._lift_normals(self._contact_normals(c))
                        nxt = min([s0 for s0, _c in starts if s0 >= c_end], default=np.inf) - self.g.hand_approach_window
                        window = max(min(c_end + self.g.hand_retreat_window, nxt), c_end) - end
                        lift = retreat_lift(t, sp[limb], sR[limb], normals, end, probe, window=window,
                                            margin=self.g.hand_retreat_margin, spread=self.g.hand_approach_spread,
                                            last=self.g.hand_retreat_rise, taper=self.g.hand_retreat_rise,
                                            least_bad=self.g.hand_retreat_least_bad)  # fmt: skip
                        sp[limb] = sp[limb] + lift[:, None] * normals
                        self._arm_only[limb] |= lift > 1e-9  # as under the grasp offsets: the arm moves the hand
                        self.retreat_lifts.append((limb, end, float(lift.max())))
                if self.g.hand_registered_after_release:
                    self._registered[limb] = self._registration(limb, t, sp[limb], sR[limb], probe)
            if self.g.hand_arm_only_near_contact:
                self._arm_only[limb] |= np.linalg.norm(off, axis=1) > 1e-9
            if obstacles and self.hand_geom[limb] >= 0:
                probe = HandBoxProbe(m, self.hand_geom[limb], self.site_id[limb], obstacles, movable)
                sp[limb] = self._take_detour(limb, sp[limb], *detour(limb, t, sp[limb], sR[limb], self._in_contact(limb),
                                             probe, self.g.hand_detour_margin, self.g.hand_detour_pre_contact))
            sv[limb][:, :3] = np.gradient(sp[limb], t, axis=0)
        grad = lambda a: np.gradient(a, t, axis=0)  # noqa: E731
        return _Refs(com=com, com_v=com_v, com_a=grad(com_v), base_p=tr.base_pos.copy(), base_v=tr.base_linvel.copy(),
                     base_a=grad(tr.base_linvel), base_R=base_R, base_w=base_w, base_alpha=grad(base_w),
                     torso_R=torso_R, torso_w=torso_w, torso_p=torso_p,
                     site_p=sp, site_R=sR, site_v=sv, site_a={l: grad(v) for l, v in sv.items()},
                     qdd=grad(tr.qd),
                     angmom=tr.angular_momentum,
                     angmom_rate=grad(tr.angular_momentum) if tr.angular_momentum is not None else None)  # fmt: skip

    def _planned_feet_share(self) -> dict[str, np.ndarray]:
        """foot -> (N,) the plan's vertical force on it averaged over the next feet_follow_lookahead s
        (forces on the grid, trapezoid integral); the feet_follow weights."""
        tr, out = self.traj, {}
        look = max(self.g.feet_follow_lookahead, 1e-6)
        for f in FEET:
            fz = tr.forces[f][:, 2] if f in tr.forces else np.zeros(tr.n)
            fz = np.maximum(fz, 0.0)
            cum = np.concatenate([[0.0], np.cumsum(0.5 * (fz[1:] + fz[:-1]) * np.diff(tr.t))])
            end = np.minimum(tr.t + look, tr.t[-1])
            span = np.maximum(end - tr.t, 1e-9)
            ahead = (np.interp(end, tr.t, cum) - cum) / span
            out[f] = np.where(end > tr.t, ahead, fz)
        return out

    def _feet_follow_target(self, data: mujoco.MjData, contacts, i: int, s: float) -> np.ndarray | None:
        """(2,) the weighted placement error of the stance feet in ``contacts``, None without one."""
        R_, num, den = self.refs, np.zeros(2), 0.0
        for f in FEET:
            if f not in contacts:
                continue
            a = self._feet_share[f]
            w = a[i] + s * (a[i + 1] - a[i])
            p = R_.site_p[f][i] + s * (R_.site_p[f][i + 1] - R_.site_p[f][i])
            num += w * (data.site_xpos[self.site_id[f]][:2] - p[:2])
            den += w
        return num / den if den > 1e-6 else None

    def _object_net_forces(self) -> dict:
        """object -> (N,3) force the grasp must give it for its planned motion, m (a + g) (dense plan,
        second differences), NaN where a support carries part of it: outside the schedule's phases
        that have it free (carried by the contacts alone), or, where the schedule does not say,
        within ``object_lift_height`` of its initial height. Why the schedule first: S2's box is
        carried below the table top it was picked from, and the height rule fed the plan's forces
        forward through the whole carry (docs/execution.md, session 29)."""
        tr, out = self.traj, {}
        said = bool(tr.phases) and all(ph.free_objects is not None for ph in tr.phases)
        free_at = [tr.phase_at(float(t)).free_objects for t in tr.t] if said else None  # per grid point
        for oid, (P, _Q) in tr.objects.items():
            so = self.world.objects.get(oid)
            if so is None or not so.movable or so.mass <= 0:
                continue
            P = np.asarray(P, float)
            a = np.gradient(np.gradient(P, tr.t, axis=0), tr.t, axis=0)
            need = so.mass * (a - self.model.opt.gravity)  # the sim's own gravity
            if free_at is not None:
                need[np.array([oid not in f for f in free_at])] = np.nan
            else:
                need[P[:, 2] < P[0, 2] + self.g.object_lift_height] = np.nan
            out[oid] = need
        return out

    def _movable_poses(self, bodies: list[int]) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        """body -> (N,3) positions, (N,4) wxyz quaternions along the grid: planned, or the initial pose."""
        m, tr, out = self.model, self.traj, {}
        for b in bodies:
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b)
            oid = next((o for o, so in self.world.objects.items() if so.body_name == name), None)
            if oid in tr.objects:  # the plan's pose is the object's CoM frame (the TO's), the body's origin is not
                P, Q = np.asarray(tr.objects[oid][0]), np.asarray(tr.objects[oid][1])
                R = np.array([frames.quat_to_matrix(q) for q in Q])
                out[b] = (P - R @ self._com_offset(b), Q)
            else:
                q0 = m.qpos0[m.jnt_qposadr[m.body_jntadr[b]] :][:7]
                out[b] = (np.repeat(q0[None, :3], tr.n, 0), np.repeat(q0[None, 3:], tr.n, 0))
        return out

    def _object_frames(self, data: mujoco.MjData, oid: str, i: int, s: float, lifted: bool = False):
        """(actual CoM, actual R, planned CoM, planned R) at grid time i + s of an object the hands
        follow: one the plan keeps at one height (pushed on the floor), or any if ``lifted``; else None."""
        tr = self.traj
        if oid not in tr.objects:
            return None
        body = self._object_body.get(oid)
        if body is None:
            name = self.world.objects[oid].body_name if oid in self.world.objects else oid
            b = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, name)
            body = self._object_body[oid] = (b, self._com_offset(b) if b >= 0 else None)
        b, off = body
        if b < 0:
            return None
        P, Q = tr.objects[oid]
        if not lifted and self._lifted_in_plan(oid):  # a lifted object: the hands carry it to the plan (a slipping box is not followed)
            return None
        R_act = data.xmat[b].reshape(3, 3)
        return (data.xpos[b] + R_act @ off, R_act, P[i] + s * (P[i + 1] - P[i]),
                frames.quat_to_matrix(Q[i if s < 0.5 else i + 1]))

    def _object_velocity_lead(self, data: mujoco.MjData, oid: str, i: int) -> np.ndarray:
        """The object's actual CoM velocity minus its plan's over grid interval i (world, m/s)."""
        b, off = self._object_body[oid]  # (set by _object_frames, called first)
        mujoco.mj_objectVelocity(self.model, data, mujoco.mjtObj.mjOBJ_BODY, b, self._vel6, 0)
        v_act = self._vel6[3:] + np.cross(self._vel6[:3], data.xmat[b].reshape(3, 3) @ off)
        P, tr = self.traj.objects[oid][0], self.traj
        return v_act - (P[i + 1] - P[i]) / (tr.t[i + 1] - tr.t[i])

    def _lifted_in_plan(self, oid: str) -> bool:
        """Whether the plan moves object ``oid`` up or down by more than 1 cm (a carried object)."""
        out = self._lifted.get(oid)
        if out is None:
            out = self._lifted[oid] = bool(np.ptp(self.traj.objects[oid][0][:, 2]) > 0.01)
        return out

    def _on_actual_object(self, data: mujoco.MjData, oid: str, p: np.ndarray, i: int, s: float,
                          lifted: bool = False) -> np.ndarray:
        """``p`` (on the planned object at grid time i + s) carried to the object's actual pose; only
        for objects the plan keeps at one height (pushed on the floor) unless ``lifted``:
        case_lift_box's box slid 1-2 cm in the grasp, hands that followed it left it 8.4 cm below its goal."""
        fr = self._object_frames(data, oid, i, s, lifted)
        if fr is None:
            return p
        c_act, R_act, c_plan, R_plan = fr
        return c_act + R_act @ (R_plan.T @ (p - c_plan))

    def _push_admittance(self, data: mujoco.MjData, limb: str, c, t: float, i: int, s: float) -> np.ndarray:
        """Shift (3,) of the hand reference along the contact normal (``WbcGains.hand_push_admittance``);
        also sets the desired normal force that :meth:`hand_feedforward` feeds forward."""
        g, tr = self.g, self.traj
        fr = self._object_frames(data, c.object_id, i, s)
        if fr is None or limb not in tr.forces:
            self._admittance.pop(limb, None)
            return np.zeros(3)
        lead = fr[0] - fr[2]  # the object's actual minus planned CoM
        held = self._admittance_keys.get(id(c))
        if held is None:  # (the contact is kept with its key, so its id is not reused)
            held = self._admittance_keys[id(c)] = (c, (c.object_id, None if c.position is None
                                                       else tuple(np.round(c.position, 6))))
        key = held[1]
        st = self._admittance.get(limb)
        if st is None or st[0] != key:
            st = self._admittance[limb] = [key, 0.0]
        n = self._contact_normals(c)[i if s < 0.5 else i + 1]
        f_plan_n = float(n @ (tr.forces[limb][i] + s * (tr.forces[limb][i + 1] - tr.forces[limb][i])))
        fb = g.push_object_gain * float(n @ lead)
        if g.push_object_damping > 0.0:
            fb += g.push_object_damping * float(n @ self._object_velocity_lead(data, c.object_id, i))
        f_des = float(np.clip(f_plan_n + fb, g.push_min_force,
                              max(f_plan_n, g.push_min_force) + g.push_max_extra))
        f_meas = float(n @ self.measured_forces[limb])
        st[1] = float(np.clip(st[1] + self.model.opt.timestep * g.hand_admittance_rate * (f_meas - f_des),
                              -g.hand_admittance_in, g.hand_admittance_out))
        self._push_force[limb] = (n, f_des)
        shift = st[1] * n
        if g.hand_tangential_backoff > 0.0:
            sp = self.refs.site_p[limb]
            p_plan = sp[i] + s * (sp[i + 1] - sp[i]) + lead
            e = data.site_xpos[self.site_id[limb]] - p_plan
            off = float(np.linalg.norm(e - n * float(n @ e)))  # along the surface
            shift = shift + n * min(g.hand_backoff_max, g.hand_tangential_backoff * max(0.0, off - g.hand_backoff_free))
        return shift

    def _release_hands(self, data: mujoco.MjData, contacts: dict, t: float, i: int, s: float) -> dict:
        """The phase's contacts less the hand contacts the controller has released (``hand_release``).

        A planned hand contact is released when its object has left the hand: the hand touched the
        object in this contact, has not touched it for ``hand_release_time`` s, and the grasp point on
        the actual object is more than ``hand_release_reach`` from the plan's hand carried with the
        torso (where the arm would be without chasing the object). It stays released until the
        plan's own release (the contact ends or changes object)."""
        g, out = self.g, dict(contacts)
        for limb in HANDS:
            c = contacts.get(limb)
            rel = self.released.get(limb)
            if c is None:  # no planned contact (the plan's own release): the released tasks blend out
                self._touched.pop(limb, None)
                if rel is not None:
                    if rel[2] is None:
                        rel = self.released[limb] = (rel[0], rel[1], t)
                    if t - rel[2] >= g.hand_release_blend:
                        del self.released[limb]
                continue
            if rel is not None:
                if rel[0] == c.object_id and rel[2] is None:
                    out.pop(limb)
                    continue
                del self.released[limb]  # another contact: starts afresh
            if self._touching(data, limb, c.object_id):
                self._touched[limb] = (c.object_id, t)
            seen = self._touched.get(limb)
            if seen is None or seen[0] != c.object_id or t - seen[1] <= g.hand_release_time:
                continue
            p_plan = self.refs.site_p[limb][i] + s * (self.refs.site_p[limb][i + 1] - self.refs.site_p[limb][i])
            grasp = self._on_actual_object(data, c.object_id, p_plan, i, s, lifted=True)
            p_body, _R = self._on_torso(data, p_plan, None, i, s)
            dist = float(np.linalg.norm(grasp - p_body))
            if dist > g.hand_release_reach:
                self.released[limb] = (c.object_id, t, None)
                self.release_events.append((limb, c.object_id, t, dist))
                out.pop(limb)
        return out

    def _body_weight(self, limb: str, t: float) -> float:
        """0..1: how far a hand is in its released state (hand reference on the plan carried with the
        torso, the arm on the plan's posture): in over ``hand_release_blend`` s from the release, out as
        long after the plan's own release."""
        rel = self.released.get(limb)
        if rel is None or self.g.hand_release_blend <= 0:
            return 0.0 if rel is None else 1.0
        w = float(smoothstep(np.clip((t - rel[1]) / self.g.hand_release_blend, 0.0, 1.0)))
        if rel[2] is not None:
            w *= 1.0 - float(smoothstep(np.clip((t - rel[2]) / self.g.hand_release_blend, 0.0, 1.0)))
        return w

    def _on_torso(self, data: mujoco.MjData, p: np.ndarray, R: np.ndarray | None, i: int, s: float):
        """Planned hand position ``p`` (and orientation ``R``) at grid time i + s carried from the
        planned to the actual torso frame."""
        Rt = self.refs.torso_R[i if s < 0.5 else i + 1]
        tp = self.refs.torso_p[i] + s * (self.refs.torso_p[i + 1] - self.refs.torso_p[i])
        Ra = data.xmat[self.torso].reshape(3, 3) @ Rt.T
        return data.xpos[self.torso] + Ra @ (p - tp), (None if R is None else Ra @ R)

    def _com_offset(self, body: int) -> np.ndarray:
        """CoM of a free body's subtree (wheels included) in its own frame, at the model's qpos0."""
        m = self.model
        d = mujoco.MjData(m)
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        return d.xmat[body].reshape(3, 3).T @ (d.subtree_com[body] - d.xpos[body])

    def _contact_starts(self, limb: str) -> list:
        """(start time, contact) of each contact of ``limb`` that follows a phase without it."""
        out, prev = [], None
        for ph in self.traj.phases:
            c = ph.contacts.get(limb)
            if c is not None and prev is None:
                out.append((ph.start, c))
            prev = c
        return out

    def reference_corrections(self) -> str:
        """One line on the geometric corrections of the hand references (for the logs): detours
        round static geoms, lifts before contacts and after releases."""
        def lifts(items):
            moved = [x for x in items if x[2] > 0.0]
            return f"{len(moved)} of {len(items)}" + (f" (up to {100 * max(x[2] for x in moved):.1f} cm)" if moved else "")
        shifted = [d for d in self.detours if d.direction is not None]
        return (f"hand references: {len(shifted)} detours round static geoms, approach lifts {lifts(self.approach_lifts)}, "
                f"retreat lifts {lifts(self.retreat_lifts)}")

    def _contact_ends(self, limb: str) -> list:
        """(release time, end time, contact) of each contact of ``limb`` that a phase without it follows. The
        release is the contact's end, or earlier the last grid time in the contact where the plan's
        force on the hand exceeds ``hand_retreat_force`` (the plan no longer uses the hand after it)."""
        tr, out, prev, start = self.traj, [], None, 0.0
        f = tr.forces.get(limb)
        for ph in tr.phases:
            c = ph.contacts.get(limb)
            if c is not None and prev is None:
                start = ph.start
            if c is None and prev is not None:
                end = ph.start
                if f is not None:
                    sel = (tr.t >= start) & (tr.t <= ph.start) & (np.linalg.norm(f, axis=1) > self.g.hand_retreat_force)
                    if np.any(sel):
                        end = float(tr.t[np.flatnonzero(sel)[-1]])
                out.append((end, ph.start, prev))
            prev = c
        return out

    def _registration(self, limb: str, t: np.ndarray, p: np.ndarray, R: np.ndarray, probe) -> list:
        """[(object, (N,) weight, (N,3) normal)]: after each contact of ``limb`` with an object the plan
        pushes on the floor, until the hand's next contact, 1 while the hand box at its planned pose
        (``p``, ``R``) is within ``hand_registered_near`` of the planned movable objects, falling
        smoothly to 0 at ``hand_registered_far`` (``WbcGains.hand_registered_after_release``); the
        normal is the released contact's outward one (``hand_registered_outward_only``)."""
        g, out = self.g, []
        starts = [s0 for s0, _c in self._contact_starts(limb)]
        for _end, c_end, c in self._contact_ends(limb):
            oid = c.object_id
            if oid not in self.traj.objects or self._lifted_in_plan(oid):
                continue
            nxt = min([s0 for s0 in starts if s0 >= c_end], default=np.inf)
            w = np.zeros(len(t))
            for k in np.flatnonzero((t >= c_end) & (t < nxt)):
                d = probe.clearance(p[k], R[k], int(k))[1]
                u = (g.hand_registered_far - d) / max(g.hand_registered_far - g.hand_registered_near, 1e-9)
                w[k] = float(smoothstep(np.clip(u, 0.0, 1.0)))
            if np.any(w > 0):  # the face's outward direction in the floor plane the object moves in
                n = self._contact_normals(c)
                level = n * np.array([1.0, 1.0, 0.0])
                size = np.linalg.norm(level, axis=1, keepdims=True)
                out.append((oid, w, np.where(size < 0.3, n, level / np.maximum(size, 1e-9))))  # < 0.3: a top face
        return out

    def _lift_normals(self, normals: np.ndarray) -> np.ndarray:
        """(N,3) directions of the approach and retreat lifts: the contact normals, tilted towards up
        on faces that look up (``hand_approach_up``: less arm mass moved back)."""
        if self.g.hand_approach_up <= 0:
            return normals
        up = np.where(normals[:, 2:3] > 0.3, self.g.hand_approach_up * np.array([0.0, 0.0, 1.0]), 0.0)
        return (normals + up) / np.linalg.norm(normals + up, axis=1, keepdims=True)

    def _hand_offsets(self, limb: str, R_hand: np.ndarray, p_site: np.ndarray | None = None) -> np.ndarray:
        """(N,3) shift of the hand target along the contact normal by the hand box's support distance,
        less the plan's own distance of the site from the surface (``hand_offset_plan_gap``).

        Why: the TO models a hand as a point on (or a ball touching) the object's surface, the sim's
        hand is a collision box around the site, so tracking the plan's site would push the box 3-5 cm
        into the object. The shift is ramped in over ``hand_offset_ramp`` s before each contact (so the
        approaching hand box stays outside the object's face) and out over ``hand_release_ramp`` s after it.
        """
        tr, g = self.traj, self.g
        half = np.asarray(HAND_COLLISION_HALF_SIZE, float)
        off = np.zeros((tr.n, 3))
        pts = tr.points.get(limb) if g.hand_offset_plan_gap and p_site is not None else None
        for ph in tr.phases:
            c = ph.contacts.get(limb)
            if c is None:
                continue
            normals = self._contact_normals(c)
            lifted = c.object_id in tr.objects and self._lifted_in_plan(c.object_id)
            squeeze = g.hand_squeeze_lifted if lifted else g.hand_squeeze
            # the plan's site height above the surface over the phase; the median, since a point on
            # the phase's boundary may carry the neighbouring phase's contact point
            gap = 0.0
            if pts is not None:
                inside = np.nonzero((tr.t >= ph.start - 1e-9) & (tr.t <= ph.end + 1e-9) & np.isfinite(pts[:, 0]))[0]
                if len(inside):
                    gap = float(np.median(np.einsum("ij,ij->i", normals[inside], p_site[inside] - pts[inside])))
            w = np.clip(np.minimum(1.0 - (ph.start - tr.t) / g.hand_offset_ramp, 1.0 - (tr.t - ph.end) / g.hand_release_ramp),
                        0.0, 1.0)  # fmt: skip
            # approach from outside: extra clearance until shortly before contact, gone just after it
            u = np.clip((ph.start + 0.1 - tr.t) / 0.2, 0.0, 1.0)
            if g.hand_offset_smooth:
                w, u = smoothstep(w), smoothstep(u)
            clear = g.hand_clearance * u
            for i in np.nonzero(w > 0)[0]:
                n = normals[i]
                d = float(np.abs(R_hand[i].T @ n) @ half) + squeeze + clear[i] - gap
                cand = w[i] * d * n
                if np.linalg.norm(cand) > np.linalg.norm(off[i]):
                    off[i] = cand
        return off

    def _contact_normals(self, c) -> np.ndarray:
        """(N,3) unit outward normal of contact ``c`` along the grid, turned with its object's planned
        orientation relative to the plan's start (the TO does the same with its contact normals)."""
        out = self._normals.get(id(c))
        if out is not None:
            return out
        tr = self.traj
        n = np.asarray(c.normal, float) / max(np.linalg.norm(c.normal), 1e-9)
        if not self.g.hand_normal_follows_object or c.object_id not in tr.objects:
            out = np.repeat(n[None], tr.n, 0)
        else:
            rel = self._object_turn.get(c.object_id)
            if rel is None:
                R = np.array([frames.quat_to_matrix(q) for q in tr.objects[c.object_id][1]])
                rel = self._object_turn[c.object_id] = R @ R[0].T
            out = rel @ n
        self._normals[id(c)] = out
        return out

    @staticmethod
    def _tangents(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Two unit tangents of the unit normal ``n`` (t1, t2, n right-handed)."""
        x, y, z = float(n[0]), float(n[1]), float(n[2])
        t1 = np.array([0.0, z, -y]) if abs(x) < 0.9 else np.array([-z, 0.0, x])  # n x e_x, or n x e_y
        t1 /= np.sqrt(t1 @ t1)
        a, b, c = t1
        return t1, np.array([y * c - z * b, z * a - x * c, x * b - y * a])

    def _pyramid(self, normal, mu: float, cache: bool = True) -> np.ndarray:
        """(5,3) rows of a linearised friction cone: 4 tangent rows (<= 0) and the normal; cached per
        normal unless ``cache`` is off (a normal that changes every step)."""
        key = (np.asarray(normal, float).tobytes(), mu) if cache else None
        rows = self._pyramids.get(key) if cache else None
        if rows is None:
            n = np.asarray(normal, float) / max(np.linalg.norm(normal), 1e-9)
            t1, t2 = self._tangents(n)
            if self.g.diamond_cone:  # MuJoCo's pyramidal cone for condim 3: edges n +- mu t1, n +- mu t2
                rows = np.array([t1 + t2 - mu * n, t1 - t2 - mu * n, -t1 + t2 - mu * n, -t1 - t2 - mu * n, n])
            else:
                rows = np.array([t1 - mu * n, -t1 - mu * n, t2 - mu * n, -t2 - mu * n, n])
            if cache:
                self._pyramids[key] = rows
        return rows

    def _in_contact(self, limb: str, before: float = 0.0, after: float = 0.0) -> np.ndarray:
        """(N,) bool: the plan has this limb in a contact phase, widened by ``before`` / ``after`` s."""
        tr = self.traj
        out = np.zeros(tr.n, bool)
        for ph in tr.phases:
            if limb in ph.contacts:
                out |= (tr.t >= ph.start - before) & (tr.t <= ph.end + after)
        return out

    def _free_of_objects(self, limb: str) -> np.ndarray:
        """(N,) bool: the hand is in no contact phase and ``guard_object_release`` s past its last one."""
        return ~self._in_contact(limb, after=self.g.guard_object_release)

    def _near_contact(self, limb: str) -> np.ndarray:
        """(N,) bool: the hand is in a contact phase or within ``hand_stiff_window`` of one."""
        return self._in_contact(limb, self.g.hand_stiff_window, self.g.hand_stiff_window)

    def _touching(self, data: mujoco.MjData, limb: str, object_id: str) -> bool:
        """True when the hand's collision box has a MuJoCo contact with a geom of ``object_id``."""
        hg = self.hand_geom.get(limb, -1)
        root = self._object_root.get(object_id)
        if root is None:
            ob = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, object_id)
            root = self._object_root[object_id] = int(self.model.body_rootid[ob]) if ob >= 0 else -1
        if hg < 0 or root < 0:
            return False
        return root in self._hand_contact_roots(data)[limb]

    def _hand_contact_roots(self, data: mujoco.MjData) -> dict[str, set]:
        """hand -> root bodies its collision box touches in the current contact list; computed once
        per control step (compute() drops the last scan: mj_step1 renews the contact list without
        changing data.time); the list is scanned with numpy, not per contact in Python."""
        key = (id(data), float(data.time), int(data.ncon))
        if self._touch_key != key:
            m, n = self.model, int(data.ncon)
            geoms = data.contact.geom[:n] if n else np.zeros((0, 2), int)
            roots = {}
            for limb, hg in self.hand_geom.items():
                if hg < 0:
                    roots[limb] = set()
                    continue
                other = np.where(geoms[:, 0] == hg, geoms[:, 1], np.where(geoms[:, 1] == hg, geoms[:, 0], -1))
                other = other[other >= 0]
                roots[limb] = set(m.body_rootid[m.geom_bodyid[other]].tolist())
            self._touch_roots, self._touch_key = roots, key
        return self._touch_roots

    def _support_box(self, data: mujoco.MjData, feet: list[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """Contact sole corners as a box (lo, hi) in the pelvis heading frame R (2x2), shrunk by the margin."""
        if not feet:
            return None
        Rp = data.xmat[self.pelvis].reshape(3, 3)
        yaw = np.arctan2(Rp[1, 0], Rp[0, 0])
        c, s_ = np.cos(yaw), np.sin(yaw)
        H = np.array([[c, s_], [-s_, c]])  # world xy -> heading frame
        pts = np.concatenate([data.xpos[b] + _SOLE_CORNERS @ data.xmat[b].reshape(3, 3).T
                              for b in (self.foot_body[lf] for lf in feet)])
        loc = pts[:, :2] @ H.T
        lo, hi = loc.min(axis=0) + self.g.com_margin, loc.max(axis=0) - self.g.com_margin
        return lo, np.maximum(hi, lo), H

    def _on_arm(self, J: np.ndarray, limb: str) -> np.ndarray:
        """``J`` with only the columns of hand ``limb``'s own arm (a task its arm alone carries out)."""
        out = np.zeros_like(J)
        cols = self._arm_cols[limb]
        out[:, cols] = J[:, cols]
        return out

    def _step_adjustment(self, data: mujoco.MjData, com: np.ndarray, com_v: np.ndarray, phase, t: float, i: int,
                         s: float) -> np.ndarray:
        """(3,) horizontal shift of a swing foot's target: ``step_adjust_gain`` times the capture
        point's error (measured CoM ``com`` + velocity ``com_v`` / omega against the plan's, the CoM
        clamp's and feet_follow's shifts included), faded in over the swing and bounded by ``step_adjust_max``."""
        g, R_ = self.g, self.refs
        c_ref = R_.com[i] + s * (R_.com[i + 1] - R_.com[i])
        v_ref = R_.com_v[i] + s * (R_.com_v[i + 1] - R_.com_v[i])
        sole_z = min(float(data.site_xpos[self.site_id[f]][2]) for f in FEET) - FOOT_SOLE_OFFSET
        omega = np.sqrt(-self.model.opt.gravity[2] / max(com[2] - sole_z, 0.3))
        err = (com[:2] - c_ref[:2] - self._com_shift - self._feet_shift) + (com_v[:2] - v_ref[:2]) / omega
        u = np.clip((t - phase.start) / max(phase.end - phase.start, 1e-3), 0.0, 1.0)
        shift = g.step_adjust_gain * float(smoothstep(u)) * err
        n = np.linalg.norm(shift)
        if n > g.step_adjust_max:
            shift *= g.step_adjust_max / n
        return np.array([shift[0], shift[1], 0.0])

    def _landing(self, limb: str, phase) -> tuple | None:
        """(object id, landing grid index) of the contact that ends swing ``phase`` of foot ``limb``
        when it is on a movable object of the plan; else None (cached per phase)."""
        key = (limb, id(phase))
        if key not in self._landings:
            out = None
            later = [ph for ph in self.traj.phases if ph.start >= phase.end - 1e-9]
            nxt = next((ph for ph in later if ph.contacts.get(limb) is not None), None)
            if nxt is not None and nxt.contacts[limb].object_id in self.traj.objects:
                out = (nxt.contacts[limb].object_id, int(np.searchsorted(self.traj.t, nxt.start - 1e-9)))
            self._landings[key] = out
        return self._landings[key]

    def _landing_shift(self, data: mujoco.MjData, limb: str, phase, t: float) -> np.ndarray:
        """(3,) shift of a swing foot's target by its landing point's displacement on the object it lands
        on (``foot_follows_object``), faded in over the first half of the swing."""
        land = self._landing(limb, phase)
        if land is None:
            return np.zeros(3)
        oid, k = land
        k = min(k, self.traj.n - 2)
        fr = self._object_frames(data, oid, k, 0.0, lifted=True)
        if fr is None:
            return np.zeros(3)
        c_act, R_act, c_plan, R_plan = fr
        p_land = self.refs.site_p[limb][k]
        shift = c_act + R_act @ (R_plan.T @ (p_land - c_plan)) - p_land
        u = np.clip((t - phase.start) / max(0.5 * (phase.end - phase.start), 1e-3), 0.0, 1.0)
        return float(smoothstep(u)) * shift

    def qp_sole_cop(self, limb: str) -> np.ndarray | None:
        """(2,) the centre of pressure (sole frame x, y, as ``FOOT_CONTACT_POINTS``) of the corner forces
        the last QP chose for stance foot ``limb``, or None (a swing foot, or under 1 N). Why: set
        against the measured one it says whether a sole on its edge was asked for or not
        (tools/exec_trace.py --cop; docs/execution.md, session 48)."""
        f = self.last_sole_forces.get(limb)
        if f is None or len(f) != len(_SOLE_CORNERS):
            return None
        n = self.model.opt.gravity / -np.linalg.norm(self.model.opt.gravity)  # the floor's normal (soles on flat tops)
        fn = f @ n
        if fn.sum() < 1.0:
            return None
        return (fn @ _SOLE_CORNERS[:, :2]) / fn.sum()

    def angular_momentum_matrix(self, data: mujoco.MjData, com: np.ndarray) -> np.ndarray:
        """A (3 x NV): the robot's angular momentum about its CoM ``com`` is A @ qvel (world frame)."""
        m, A = self.model, np.zeros((3, NV))
        for b in self._robot_bodies:
            mujoco.mj_jacBodyCom(m, data, self._jp, self._jr, b)
            R = data.ximat[b].reshape(3, 3)
            inertia = (R * m.body_inertia[b]) @ R.T
            A += inertia @ self._jr[:, self.dofs] + m.body_mass[b] * _skew(data.xipos[b] - com) @ self._jp[:, self.dofs]
        return A

    def reference_qpos(self, t: float) -> np.ndarray:
        """Planned 36-D robot configuration at trajectory time t (linear interpolation)."""
        i, s = self.traj.index_at(t)
        a, b = self.traj.qpos(i), self.traj.qpos(i + 1)
        q = a + s * (b - a)
        q[3:7] /= np.linalg.norm(q[3:7])
        return q

    def _grasp_rows(self, contacts: dict, hand_points: list, bhand: np.ndarray, Ahand: np.ndarray,
                    H: np.ndarray, f: np.ndarray, col0: int, mom0: int | None, i: int, s: float,
                    data: mujoco.MjData):
        """The hands' force rows of the QP: (lower, upper, equality flags) of ``Ahand``'s rows and the
        grasp rows (A, lower, upper). Each hand's force is fixed to ``bhand`` unless
        ``grasp_force_in_qp`` and it holds a carried object with another hand: then the first such
        hand's rows fix the hands' sum (``Ahand`` and the cost ``H``, ``f`` are changed in place), each
        hand's force is bounded by its pyramid and, with patch moments (columns from ``mom0``), its
        moment by the patch and torsion times the normal force the QP chooses."""
        g, nx = self.g, Ahand.shape[1]
        lo, hi, eq = bhand.copy(), bhand.copy(), np.ones(len(bhand), bool)
        rows, glo, ghi = [], [], []
        groups: dict[str, list[int]] = {}
        if g.grasp_force_in_qp:
            for k, (limb, _j) in enumerate(hand_points):
                oid = contacts[limb].object_id
                if np.any(bhand[3 * k : 3 * k + 3] != 0.0) and limb not in self._push_force and self._carried_at(oid, i):
                    groups.setdefault(oid, []).append(k)
        for ks in groups.values():
            if len(ks) < 2:
                continue
            k0 = ks[0]
            lo[3 * k0 : 3 * k0 + 3] = hi[3 * k0 : 3 * k0 + 3] = sum(bhand[3 * k : 3 * k + 3] for k in ks)
            for k in ks:
                c = col0 + 3 * k
                want = bhand[3 * k : 3 * k + 3]
                if k != k0:
                    Ahand[3 * k0 : 3 * k0 + 3, c : c + 3] = np.eye(3)
                    Ahand[3 * k : 3 * k + 3] = 0.0
                    lo[3 * k : 3 * k + 3], hi[3 * k : 3 * k + 3], eq[3 * k : 3 * k + 3] = -1e30, 1e30, False
                n, turned = self._grasp_normal(contacts[hand_points[k][0]], i, s, data)
                A = np.zeros((5, nx))
                A[:, c : c + 3] = self._pyramid(n, g.mu_grasp, cache=not turned)
                rows.append(A)
                glo += [-1e30] * 4 + [g.grasp_min_normal]
                ghi += [0.0] * 4 + [g.f_max]
                if mom0 is not None:  # |tau . axis| <= size (n . f) for the patch's two tilts and the torsion
                    t1, t2 = self._tangents(n)
                    m = mom0 + 3 * k
                    for axis, size in ((t1, g.hand_patch_half), (t2, g.hand_patch_half), (n, g.hand_torsion)):
                        for sign in (1.0, -1.0):
                            A = np.zeros((1, nx))
                            A[0, m : m + 3] = sign * axis
                            A[0, c : c + 3] = -size * n
                            rows.append(A)
                            glo.append(-1e30)
                            ghi.append(0.0)
                H[c : c + 3, c : c + 3] += g.w_grasp_force * np.eye(3)
                f[c : c + 3] -= g.w_grasp_force * want
            if g.w_grasp_moment > 0.0:
                Am, tau_des = self._grasp_moment_rows(data, contacts[hand_points[k0][0]].object_id,
                                                      [hand_points[k][0] for k in ks], [col0 + 3 * k for k in ks],
                                                      [mom0 + 3 * k for k in ks] if mom0 is not None else [],
                                                      nx, i, s)
                H += g.w_grasp_moment * (Am.T @ Am)
                f -= g.w_grasp_moment * (Am.T @ tau_des)
        A = np.vstack(rows) if rows else np.zeros((0, nx))
        return lo, hi, eq, A, np.array(glo, float), np.array(ghi, float)

    def _grasp_moment_rows(self, data: mujoco.MjData, oid: str, limbs: list[str], fcols: list[int],
                           mcols: list[int], nx: int, i: int, s: float) -> tuple[np.ndarray, np.ndarray]:
        """(A (3, nx), tau (3,)): A x is the moment the hands put on object ``oid`` about its actual CoM
        (the QP's forces and patch moments act on the robot, the object gets their opposites); tau is
        the moment that turns the object towards its planned orientation with the object's inertia."""
        g = self.g
        A = np.zeros((3, nx))
        fr = self._object_frames(data, oid, i, s, lifted=True)  # None unless the body exists
        if fr is None:
            return A, np.zeros(3)
        b = self._object_body[oid][0]
        c_act, R_act, _c_plan, R_plan = fr
        for limb, col in zip(limbs, fcols):
            A[:, col : col + 3] = -_skew(data.site_xpos[self.site_id[limb]] - c_act)
        for col in mcols:
            A[:, col : col + 3] = -np.eye(3)
        Ri = data.ximat[b].reshape(3, 3)
        inertia = Ri @ np.diag(self.model.body_inertia[b]) @ Ri.T
        mujoco.mj_objectVelocity(self.model, data, mujoco.mjtObj.mjOBJ_BODY, b, self._vel6, 0)
        w = self._vel6[:3]
        alpha = g.grasp_orientation_kp * _rot_error(R_plan, R_act) - g.grasp_orientation_kd * w
        return A, inertia @ alpha + np.cross(w, inertia @ w)

    def _grasp_normal(self, c, i: int, s: float, data: mujoco.MjData) -> tuple[np.ndarray, bool]:
        """(unit normal of grasp contact ``c`` at grid time i + s, whether it was turned to the
        object's actual pose): the plan's normal, or with ``grasp_normal_on_actual_object`` that
        normal turned by the object's actual-vs-planned rotation."""
        n = self._contact_normals(c)[i]
        if self.g.grasp_normal_on_actual_object:
            fr = self._object_frames(data, c.object_id, i, s, lifted=True)
            if fr is not None:
                return fr[1] @ (fr[3].T @ n), True
        return n, False

    def _carried_at(self, oid: str, i: int) -> bool:
        """Whether grid interval i has ``oid`` carried by the hands alone (its needed force is fed forward)."""
        need = self._object_net.get(oid)
        return need is not None and not (np.isnan(need[i, 0]) or np.isnan(need[i + 1, 0]))

    def hand_feedforward(self, limb: str, contacts: dict, i: int, s: float) -> np.ndarray:
        """Force on the robot at hand ``limb`` (world, N) fed forward at grid time i + s of an engaged grasp:
        the plan's, or on a lifted object (``hand_force_from_object_motion``) the plan's squeeze (times
        ``grasp_squeeze_scale``) plus this hand's share of what the object's planned motion needs."""
        tr = self.traj

        def lerp(a):
            return a[i] + s * (a[i + 1] - a[i])

        f = lerp(tr.forces[limb])
        if limb in self._push_force:  # admittance on a pushed object: its desired normal force
            n, f_des = self._push_force[limb]
            return f + (f_des - float(n @ f)) * n
        oid = contacts[limb].object_id
        if not self._carried_at(oid, i):
            return f
        need = self._object_net[oid]
        mates = [l for l in HANDS if contacts.get(l) is not None and contacts[l].object_id == oid and l in tr.forces]
        mean = sum(lerp(tr.forces[l]) for l in mates) / len(mates)
        squeeze = self.g.grasp_squeeze_scale * (f - mean)
        return squeeze - lerp(need) / len(mates)  # the object receives -f (Newton's third law)

    # ---------------------------------------------------------------------------- control
    def reset(self, data: mujoco.MjData) -> None:
        """Start the trajectory clock now."""
        self.t0 = float(data.time)
        self.status = WbcStatus()
        self._engaged.clear()
        self._last_touch.clear()
        self._touched.clear()
        self.released.clear()
        self._swing_start.clear()
        self._admittance.clear()
        self._com_shift[:] = 0.0
        self._feet_shift[:] = 0.0
        self._angmom_prev = None
        self._touch_key = None
        self._qp_working_set = None

    def observe(self, data: mujoco.MjData) -> None:
        """Read the contact forces of the step just taken (call after ``mj_step2``: only then do
        MuJoCo's contact list and constraint forces belong to the same step)."""
        self.measured_forces = self._meter.measure(data)

    def com_gains_at(self, t: float) -> tuple[float, float]:
        """(kp, kd) of the CoM task at trajectory time t: the carry gains where the schedule has an
        object carried free, else com_kp / com_kd."""
        return self._com_gains(self.traj.phase_at(min(t, self.traj.duration)))

    def _com_gains(self, phase) -> tuple[float, float]:
        g = self.g
        if (g.carry_com_kp > 0 or g.carry_com_kd > 0) and phase is not None and phase.free_objects:
            return g.carry_com_kp or g.com_kp, g.carry_com_kd or g.com_kd
        return g.com_kp, g.com_kd

    def trajectory_time(self, data: mujoco.MjData) -> float:
        return float(data.time) - self.t0

    def compute(self, data: mujoco.MjData) -> np.ndarray:
        """Joint torques (29,) for the current state (after mj_step1: kinematics, qM, bias are current)."""
        m, g, tr, R_ = self.model, self.g, self.traj, self.refs
        t = self.trajectory_time(data)
        i, s = tr.index_at(t)
        after_end = t >= tr.duration
        self._push_force.clear()
        self._touch_key = None  # mj_step1 has just recomputed the contacts (at an unchanged data.time)

        def lerp(a):
            return a[i] + s * (a[i + 1] - a[i])

        def dlerp(a):  # velocities/accelerations: zero once the plan has ended (hold)
            return np.zeros(a.shape[1:]) if after_end else lerp(a)

        phase = tr.phase_at(min(t, tr.duration))
        planned = phase.contacts if phase is not None else {f: None for f in FEET}
        contacts = self._release_hands(data, planned, t, i, s) if g.hand_release else planned
        released_w = {limb: self._body_weight(limb, t) for limb in HANDS}  # 0..1 per hand, this step
        follow = g.feet_follow
        if any((c := contacts.get(f)) is not None and c.object_id in tr.objects for f in FEET):
            follow = max(follow, g.feet_follow_on_objects)   # a foot stands on a plan's object
        if (follow > 0 or np.any(self._feet_shift != 0.0)) and not after_end:
            target = self._feet_follow_target(data, contacts, i, s)
            if target is not None:
                a = min(m.opt.timestep / g.feet_follow_time, 1.0) if g.feet_follow_time > 0 else 1.0
                self._feet_shift += a * (follow * target - self._feet_shift)
        body_frame_hands = False  # some free hand tracked in the torso frame this step
        dofs = self.dofs
        v = data.qvel[dofs]
        qj = data.qpos[self.bq + 7 : self.bq + 7 + NJ]
        vj = v[6:]

        rows_A: list[np.ndarray] = []
        rows_b: list[np.ndarray] = []
        rows_w: list[np.ndarray] = []

        def task(A, b, w):
            rows_A.append(A)
            rows_b.append(b)
            rows_w.append(np.full(len(b), w) if np.isscalar(w) else w)

        # --- sites: feet (contact or swing) and hands
        mujoco.mj_jacSubtreeCom(m, data, self._jp, self.pelvis)  # CoM task, step adjustment
        Jc = self._jp[:, dofs].copy()
        com = data.subtree_com[self.pelvis]

        site_J = {}
        corner_J = {}
        for limb, sid in self.site_id.items():
            mujoco.mj_jacSite(m, data, self._jp, self._jr, sid)
            J = np.empty((6, NV))
            J[:3], J[3:] = self._jp[:, dofs], self._jr[:, dofs]
            site_J[limb] = J
            mujoco.mj_jacDot(m, data, self._jdp, self._jdr, data.site_xpos[sid], m.site_bodyid[sid])
            jdv = np.empty(6)
            jdv[:3], jdv[3:] = self._jdp[:, dofs] @ v, self._jdr[:, dofs] @ v
            vel = J @ v
            p, Rm = data.site_xpos[sid], data.site_xmat[sid].reshape(3, 3)
            if limb in FEET:
                if limb in contacts:
                    task(J, -jdv - g.contact_kd * vel, g.w_contact)
                    # sole corner point Jacobians (forces act there)
                    bid = self.foot_body[limb]
                    r = data.xpos[bid] + _SOLE_CORNERS @ data.xmat[bid].reshape(3, 3).T - p  # (4, 3)
                    corner_J[limb] = list(_point_jacobians(J, r))
                else:
                    p_plan, v_ref, a_ref = lerp(R_.site_p[limb]), dlerp(R_.site_v[limb]), dlerp(R_.site_a[limb])
                    p_ref = p_plan
                    start = self._swing_start.get(limb)
                    if start is None or start[0] is not phase:  # lift-off: remember where the foot left
                        start = self._swing_start[limb] = (phase, p.copy(), t)
                    u = (t - start[2]) / g.swing_blend_time if g.swing_blend_time > 0 else 1.0
                    if u < 1.0:  # blend from the actual lift-off point into the plan (no kick)
                        w = u * u * (3 - 2 * u)
                        wd = 6 * u * (1 - u) / g.swing_blend_time
                        p_ref = start[1] + w * (p_plan - start[1])
                        v_ref = v_ref.copy()
                        v_ref[:3] = w * v_ref[:3] + wd * (p_plan - start[1])
                        a_ref = w * a_ref
                    if g.step_adjust_gain > 0 and phase is not None:
                        p_ref = p_ref + self._step_adjustment(data, com, Jc @ v, phase, t, i, s)
                    if g.foot_follows_object and phase is not None:
                        p_ref = p_ref + self._landing_shift(data, limb, phase, t)
                    e = np.concatenate([p_ref - p, _rot_error(R_.site_R[limb][i if s < 0.5 else i + 1], Rm)])
                    b = a_ref + g.foot_kp * e + g.foot_kd * (v_ref - vel) - jdv
                    task(J, b, g.w_swing)
            else:
                p_ref = p_plan = lerp(R_.site_p[limb])
                registered = None  # free in the plan, near an object it pushed: the object's displacement
                if planned.get(limb) is None:
                    for oid, wr, nr in self._registered.get(limb, ()):
                        w_r = wr[i] + s * (wr[i + 1] - wr[i])
                        if w_r > 0.0:
                            registered = w_r * (self._on_actual_object(data, oid, p_plan, i, s) - p_plan)
                            if g.hand_registered_outward_only:  # never into the face it let go of
                                n = nr[i if s < 0.5 else i + 1]
                                registered = registered - min(float(n @ registered), 0.0) * n
                if g.hand_follows_object and limb in contacts and contacts[limb] is not None:
                    p_ref = self._on_actual_object(data, contacts[limb].object_id, p_ref, i, s)
                    if g.hand_push_admittance:
                        p_ref = p_ref + self._push_admittance(data, limb, contacts[limb], t, i, s)
                R_ref = R_.site_R[limb][i if s < 0.5 else i + 1]
                wb = released_w[limb]
                if wb > 0.0:  # released: the plan's hand carried with the torso
                    p_body, R_body = self._on_torso(data, p_plan, R_ref, i, s)
                    p_ref = p_ref + wb * (p_body - p_ref)
                stiff = self._hand_stiff[limb][i if s < 0.5 else i + 1]
                body_frame = g.free_hand_body_frame and not stiff and wb == 0.0
                if body_frame:  # a free hand: the plan's hand carried with the actual torso, moved by its arm
                    body_frame_hands = True
                    p_ref, R_ref = self._on_torso(data, p_plan, R_ref, i, s)
                if registered is not None:
                    p_ref = p_ref + registered
                self.registered_shifts[limb] = registered if registered is not None else _ZERO3
                e = p_ref - p
                kp, kd, wh = (g.hand_kp, g.hand_kd, g.w_hand) if stiff else (g.free_hand_kp, g.free_hand_kd, g.w_free_hand)
                # (a free hand in the torso frame keeps the plan's world velocity and acceleration as
                # references: with its velocity and acceleration relative to the torso instead, 6 of 12
                # push plans executed against 9: docs/execution.md, session 11)
                b = dlerp(R_.site_a[limb])[:3] + kp * e + kd * (dlerp(R_.site_v[limb])[:3] - vel[:3]) - jdv[:3]
                Jh = J[:3]
                if body_frame or (g.hand_detour_arm_only and (self._arm_only[limb][i] or self._arm_only[limb][i + 1])):
                    Jh = self._on_arm(Jh, limb)  # the arm's own correction: the hand task may not move the body
                if wb > 0.0 and g.hand_release_posture > 0:
                    wh *= 1.0 - wb
                task(Jh, b, wh)
                eo = _rot_error(R_ref, Rm)
                if wb > 0.0:
                    eo = eo + wb * (_rot_error(R_body, Rm) - eo)
                bo = kp * eo + kd * (dlerp(R_.site_v[limb])[3:] - vel[3:]) - jdv[3:]
                w_ori = g.w_hand_ori if stiff else g.w_free_hand_ori
                if limb in contacts:
                    w_ori = g.w_hand_ori_contact
                elif limb in self.released and self.released[limb][2] is None:  # released: back on over the blend
                    w_ori = g.w_hand_ori_contact + wb * (w_ori - g.w_hand_ori_contact)
                if wb > 0.0 and g.hand_release_posture > 0:
                    w_ori *= 1.0 - wb
                task(self._on_arm(J[3:], limb) if body_frame else J[3:], bo, w_ori)

        # --- CoM (Jc, com from the top)
        com_ref = lerp(R_.com)
        if np.any(self._feet_shift != 0.0):  # onto the real stance feet (feet_follow)
            com_ref = com_ref.copy()
            com_ref[:2] += self._feet_shift
        feet = [lf for lf in FEET if lf in corner_J]
        box = self._support_box(data, feet) if g.com_margin > 0 else None
        shift = np.zeros(2)
        if box is not None:  # keep the CoM reference a margin inside the support (marginal plans tip over)
            lo, hi, Hh = box
            loc = Hh @ com_ref[:2]
            shift = Hh.T @ (np.clip(loc, lo, hi) - loc)
        if g.com_clamp_time > 0:  # the shift follows the support's changes smoothly (first order)
            self._com_shift += min(m.opt.timestep / g.com_clamp_time, 1.0) * (shift - self._com_shift)
            shift = self._com_shift
        if np.any(shift != 0.0):
            com_ref = com_ref.copy()
            com_ref[:2] += shift
        if after_end and g.hold_recentre_time > 0:  # hold: move the CoM over the middle of the soles
            if feet:
                mid = np.mean([data.xpos[self.foot_body[lf]] + data.xmat[self.foot_body[lf]].reshape(3, 3)
                               @ _SOLE_CORNERS.mean(axis=0) for lf in feet], axis=0)
                a = min((t - tr.duration) / g.hold_recentre_time, 1.0)
                com_ref = com_ref.copy()
                com_ref[:2] += a * (mid[:2] - com_ref[:2])
        kp, kd = self._com_gains(phase)
        b = dlerp(R_.com_a) + kp * (com_ref - com) + kd * (dlerp(R_.com_v) - Jc @ v)
        task(Jc, b, g.w_com)
        # --- centroidal angular momentum (A_dot v by a finite difference over the control period)
        if g.w_angular_momentum > 0 and R_.angmom is not None:
            A_L = self.angular_momentum_matrix(data, com)
            prev = self._angmom_prev
            dt = float(data.time) - prev[0] if prev is not None else 0.0
            bias = (A_L - prev[1]) @ v / dt if dt > 0 else np.zeros(3)
            self._angmom_prev = (float(data.time), A_L)
            b = dlerp(R_.angmom_rate) + g.angular_momentum_kd * (lerp(R_.angmom) - A_L @ v) - bias
            task(A_L, b, g.w_angular_momentum)
        # --- pelvis orientation and position
        mujoco.mj_jacBody(m, data, self._jp, self._jr, self.pelvis)
        Rp = data.xmat[self.pelvis].reshape(3, 3)
        Jr = self._jr[:, dofs]
        b = dlerp(R_.base_alpha) + g.base_kp * _rot_error(R_.base_R[i if s < 0.5 else i + 1], Rp) \
            + g.base_kd * (dlerp(R_.base_w) - Jr @ v)
        task(Jr, b, g.w_base_ori)
        Jp = self._jp[:, dofs]
        pp = data.xpos[self.pelvis]
        b = dlerp(R_.base_a) + g.base_kp * (lerp(R_.base_p) - pp) + g.base_kd * (dlerp(R_.base_v) - Jp @ v)
        task(Jp, b, g.w_base_pos)
        # --- torso orientation, while a hand task acts on its arm only (a detour, a grasp offset, a free
        # hand in the torso frame): those tasks leave the waist free
        arm_only = g.hand_detour_arm_only and any(self._arm_only[l][i] or self._arm_only[l][i + 1] for l in HANDS)
        if arm_only or body_frame_hands:
            mujoco.mj_jacBody(m, data, self._jp, self._jr, self.torso)
            Jt = self._jr[:, dofs]
            Rt = data.xmat[self.torso].reshape(3, 3)
            e_t = _rot_error(R_.torso_R[i if s < 0.5 else i + 1], Rt)
            b = g.base_kp * e_t + g.base_kd * (dlerp(R_.torso_w) - Jt @ v)
            task(Jt, b, g.w_base_ori)
        # --- posture
        q_ref = lerp(tr.q)
        b = dlerp(R_.qdd) + g.posture_kp * (q_ref - qj) + g.posture_kd * (dlerp(tr.qd) - vj)
        wp = np.full(NJ, g.w_posture)
        if g.hand_release_posture > 0:
            for limb in HANDS:
                wb = released_w[limb]
                if wb > 0.0:
                    cols = self._arm_cols[limb] - 6
                    wp[cols] = wp[cols] + wb * (g.hand_release_posture - wp[cols])
        task(_JOINT_ROWS, b, wp)

        A = np.vstack(rows_A)
        bb = np.concatenate(rows_b)
        w = np.concatenate(rows_w)
        Aw = A * w[:, None]
        Hqq = A.T @ Aw
        Hqq[_DIAG_NV] += g.reg_qdd
        gq = -Aw.T @ bb

        # --- contact force variables and their constraints
        points: list[tuple[str, np.ndarray, np.ndarray, float, float]] = []  # (limb, J(3xNV), normal, mu, fmin)
        for limb in FEET:
            if limb in corner_J:
                n = contacts[limb].normal if contacts[limb] is not None else np.array([0.0, 0.0, 1.0])
                for cj in corner_J[limb]:
                    points.append((limb, cj, n, g.mu_foot, 0.0))
        hand_points = [(limb, site_J[limb][:3]) for limb in HANDS if limb in contacts and contacts[limb] is not None]
        nfoot = 3 * len(points)
        nf = nfoot + 3 * len(hand_points)
        nm = 3 * len(hand_points) if g.hand_patch_half > 0 else 0  # hand patch moments, after the forces
        nx = NJ + NV + nf + nm
        H = np.zeros((nx, nx))
        f = np.zeros(nx)
        H[NJ : NJ + NV, NJ : NJ + NV] = Hqq
        f[NJ : NJ + NV] = gq
        # (the torque block stays empty: the QP is solved without the torques, see below, and their
        # regulariser reg_tau enters there)
        diag = np.arange(nx)
        H[diag[NJ + NV : NJ + NV + nf], diag[NJ + NV : NJ + NV + nf]] = g.reg_force
        H[diag[NJ + NV + nf :], diag[NJ + NV + nf :]] = g.w_hand_moment
        # force tracking: per foot, the sum of its corner forces -> planned force
        by_limb: dict[str, list[int]] = {}
        for k, (limb, *_r) in enumerate(points):
            by_limb.setdefault(limb, []).append(k)
        for k, (limb, _j) in enumerate(hand_points):
            by_limb[limb] = [len(points) + k]
        for limb, ks in by_limb.items():
            if limb in HANDS:
                continue
            f_ref = lerp(tr.forces[limb]) if limb in tr.forces else np.zeros(3)
            # w_force |sum of the limb's point forces - f_ref|^2 (its points are consecutive)
            a, e = NJ + NV + 3 * ks[0], NJ + NV + 3 * ks[-1] + 3
            H[a:e, a:e] += g.w_force * _summed_points(len(ks))
            f[a:e] -= g.w_force * np.tile(f_ref, len(ks))

        # dynamics: M qdd - S^T tau - Jc^T f = -h (the tau columns, -I on the joint rows, are left
        # out: the joint rows are solved for tau below)
        mujoco.mj_fullM(m, data, self._M)
        Mr = self._M[dofs, dofs]
        h = data.qfrc_bias[dofs] - data.qfrc_passive[dofs]
        Aeq = np.zeros((NV, nx))
        Aeq[:, NJ : NJ + NV] = Mr
        for k, cj in enumerate([p[1] for p in points] + [hp[1] for hp in hand_points]):
            Aeq[:, NJ + NV + 3 * k : NJ + NV + 3 * k + 3] = -cj.T
        if nm:
            for k, (limb, _j) in enumerate(hand_points):
                Aeq[:, NJ + NV + nf + 3 * k : NJ + NV + nf + 3 * k + 3] = -site_J[limb][3:].T
        beq = -h
        # hands: the planned force (on the robot) is imposed as feed-forward, not chosen by the QP,
        # so the QP can never lean on a free object as if it were a support
        for limb in HANDS:
            if limb not in contacts or contacts[limb] is None:  # a free hand: the next grasp starts afresh
                self._last_touch.pop(limb, None)
        Ahand = np.zeros((3 * len(hand_points), nx))
        bhand = np.zeros(3 * len(hand_points))
        for k, (limb, _j) in enumerate(hand_points):
            c = NJ + NV + nfoot + 3 * k
            Ahand[3 * k : 3 * k + 3, c : c + 3] = np.eye(3)
            touching = self._touching(data, limb, contacts[limb].object_id)
            if self._engaged.get(limb) is not phase:  # latch: hand touches its object, or is at its target
                close = np.linalg.norm(lerp(R_.site_p[limb]) - data.site_xpos[self.site_id[limb]]) < g.hand_engage_error
                if close or touching:
                    self._engaged[limb] = phase
                    # engaged at its target before touching: the object gets hand_lost_time to be felt
                    # (only at the start of a grasp; the grasp's later phases re-engage but keep the clock)
                    self._last_touch.setdefault(limb, t)
            if touching:
                self._last_touch[limb] = t
            lost = g.hand_lost_time > 0 and t - self._last_touch.get(limb, -np.inf) > g.hand_lost_time
            if self._engaged.get(limb) is phase and limb in tr.forces and not lost:
                bhand[3 * k : 3 * k + 3] = self.hand_feedforward(limb, contacts, i, s)
                if g.push_feedforward_measured and touching and limb in self._push_force:
                    bhand[3 * k : 3 * k + 3] = self.measured_forces.get(limb, bhand[3 * k : 3 * k + 3])
        hand_lo, hand_hi, hand_eq, Agrasp, grasp_lo, grasp_hi = self._grasp_rows(
            contacts, hand_points, bhand, Ahand, H, f, NJ + NV + nfoot, NJ + NV + nf if nm else None, i, s, data)
        # friction pyramids: 4 tangent rows + normal bounds per point
        Ain = np.zeros((5 * len(points), nx))
        bu = np.zeros(5 * len(points))
        bl = np.full(5 * len(points), -1e30)
        for k, (_l, _cj, n, mu, fmin) in enumerate(points):
            c = NJ + NV + 3 * k
            Ain[5 * k : 5 * k + 5, c : c + 3] = self._pyramid(n, mu)
            bu[5 * k + 4], bl[5 * k + 4] = g.f_max, fmin
        Amom = np.zeros((nm, nx))
        mlim = np.zeros(nm)
        if nm:  # the patch moment's bounds: from the normal force fed forward (0 when nothing is)
            for k, (limb, _j) in enumerate(hand_points):
                n = self._contact_normals(contacts[limb])[i]
                t1, t2 = self._tangents(n)
                fn = max(0.0, float(n @ bhand[3 * k : 3 * k + 3]))
                Amom[3 * k : 3 * k + 3, NJ + NV + nf + 3 * k : NJ + NV + nf + 3 * k + 3] = np.array([t1, t2, n])
                mlim[3 * k : 3 * k + 3] = fn * np.array([g.hand_patch_half, g.hand_patch_half, g.hand_torsion])
        # The joint rows of the dynamics give the torques, tau = B y - c with y = (qdd, forces,
        # moments): the QP is solved in y alone (the same optimum, 29 fewer variables; daqp's dense
        # setup, most of its time, shrinks about 2.5x). Torque limits become rows on y.
        B, c = Aeq[6:, NJ:], beq[6:]
        Hy = H[NJ:, NJ:] + g.reg_tau * (B.T @ B)
        fy = f[NJ:] - g.reg_tau * (B.T @ c)
        self.guard_rows = self.guard.rows(data, dofs) if self.guard is not None else []
        if self.object_guard is not None:
            skip = {k for limb, keys in self._object_pairs.items()
                    if not self._object_free[limb][i] for k in keys}
            rows = self.object_guard.rows(data, dofs, skip)
            for r in rows:   # the hand's own arm keeps it off: as a free hand's task, the row may not move the body
                r.row = self._on_arm(r.row[None, :], self._hand_of_pair[r.pair])[0]
            self.guard_rows = self.guard_rows + rows
        Aguard = np.zeros((len(self.guard_rows), nx - NJ))
        for k, gr in enumerate(self.guard_rows):
            Aguard[k, :NV] = gr.row   # y starts with qdd
        guard_lo = np.array([gr.lower for gr in self.guard_rows])
        A_all = np.vstack([Aeq[:6, NJ:], B, Ahand[:, NJ:], Ain[:, NJ:], Amom[:, NJ:], Agrasp[:, NJ:], Aguard])
        upper = np.concatenate([beq[:6], self.limits + c, hand_hi, bu, mlim, grasp_hi, np.full(len(guard_lo), 1e30)])
        lower = np.concatenate([beq[:6], -self.limits + c, hand_lo, bl, -mlim, grasp_lo, guard_lo])
        sense = np.zeros(len(upper), np.int32)
        sense[:6] = 5  # the floating base's rows: equalities
        sense[6 + NJ : 6 + NJ + len(bhand)] = np.where(hand_eq, 5, 0)  # the hands' fed-forward forces
        key = tuple(sorted(by_limb))
        layout = (key, nx, len(upper), tuple(gr.pair for gr in self.guard_rows))
        if self._qp_working_set is not None and self._qp_working_set[0] == layout:
            sense |= self._qp_working_set[1]  # warm start: the last step's active inequalities
        y, _fval, flag, info = daqp.solve(Hy, fy, A_all, upper, lower, sense)
        ok = flag >= 1 and np.all(np.isfinite(y))
        x = np.concatenate([B @ y - c, y]) if ok else y
        self._qp_working_set = None
        if ok and isinstance(info, dict) and "lam" in info:
            lam = np.asarray(info["lam"])
            active = (lam != 0.0) & (sense & 4 == 0)  # inequalities only: equalities are immutable (5)
            ws = np.where(active, np.where(lam < 0.0, 3, 1), 0).astype(np.int32)  # 1 active, +2 at its lower bound
            self._qp_working_set = (layout, ws)
        st = self.status
        st.t_ref, st.qp_ok, st.contacts = t, bool(ok), key
        if ok:
            tau = np.clip(x[:NJ], -self.limits, self.limits)
            self._last_tau = tau
            self.last_qdd = y[:NV].copy()
            self.last_forces = {limb: sum(x[NJ + NV + 3 * k : NJ + NV + 3 * k + 3] for k in ks) for limb, ks in by_limb.items()}
            self.last_sole_forces = {limb: x[NJ + NV + 3 * ks[0] : NJ + NV + 3 * ks[-1] + 3].reshape(-1, 3)
                                     for limb, ks in by_limb.items() if limb in FEET}
            self.last_hand_moments = {limb: x[NJ + NV + nf + 3 * k : NJ + NV + nf + 3 * k + 3]
                                      for k, (limb, _j) in enumerate(hand_points)} if nm else {}
            for limb in HANDS:
                if limb in planned and planned[limb] is not None and limb not in by_limb:
                    self.last_forces[limb] = np.zeros(3)  # a released hand: no contact force
            st.qp_iterations = int(info.get("iterations", 0)) if isinstance(info, dict) else 0
        else:
            st.qp_failures += 1
            tau = self._last_tau
        # tracking status
        ep = float(np.linalg.norm(data.qpos[self.bq : self.bq + 3] - lerp(tr.base_pos)))
        ej = qj - q_ref
        st.base_position_error = ep
        st.joint_error_rms = float(np.sqrt(ej @ ej / NJ))
        st.joint_error_max = float(np.abs(ej).max())
        return tau
