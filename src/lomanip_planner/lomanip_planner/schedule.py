"""Contact schedule between keyframes: footsteps, hand contacts made and broken, carried objects.

One keyframe per subtask (retargeted configuration + its contacts). Between the robot's current
stance and each keyframe the schedule inserts:

1. walking: footsteps from the current feet to the keyframe's feet (each step = a single-support
   phase with the swing foot free, then a double-support phase), at most ``max_step_length`` per
   step horizontally, onto the floor or onto an object's top (stepping on the box in S1: the last
   step of each foot, a longer one); hands that hold a
   carried object keep holding it and the object moves with them (``free``);
2. the manipulation of the subtask, from its verb and its contacts:
   * pick / grab / lift / take: reach (no hand contact) -> grasp (hands on the object, object still;
     the keyframe) -> lift (object ``free``, carried from then on). The lift opens the next subtask
     (as in the hand-written fixtures); in the plan's last subtask a prompt that says so ("pick
     up", "lift", ...) lifts it free, and a grab ("grab the basket") lifts it ``Timing.final_lift``
     to a placement goal above where it rests and holds it there to the end;
   * place / put / set: lower the carried object to its placement goal (``free``) -> release (hands
     still in contact, object resting) -> retract (hands free); the object is no longer carried
     and rests (``supported``) on what it was set on to the end of the subtask, then stays put;
   * push: walk up to the keyframe's feet, reach and grasp (the keyframe), then the object moves
     (``rolling`` for wheeled objects, otherwise ``supported``, i.e. sliding) while the robot walks
     behind it to ``push_feet``, and its placement goal (the request's, or keyframes.PUSH_DISTANCE
     straight ahead) holds at the end of the push -> release -> retract; objects placed on it
     earlier ride on it (``attached``, S2's box on the trolley);
   * step on / climb: the feet end on the object's top (handled by the footsteps).
   A prompt may chain several ("step on the box and grab the basket").

The output uses lomanip_to's problem types, so a schedule goes straight into the TO. Timing comes
from :class:`Timing` (parameters, not constants).  Footsteps follow the shortest route of the
mid-feet point round the footprints of the objects the robot does not hold or step onto
(:mod:`lomanip_to.route`, objects at their start or placed poses); simplification (named): a
polyline route with the feet at the start stance's width either side of it, not a footstep search
with kinematic reachability.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from lomanip_to.problem import FLOOR, STANCE, WALKING, ContactPhase, ContactSpec, Keyframe, ObjectMotion, PlacementGoal
from lomanip_to.discretize import obj_prims_world, outside_top
from lomanip_to.route import Footprint, footprint_of, point_along, route_length, shortest_route, turns, walking_heading

from .footsteps import StepLimits, Walk, plan_rounds, uniform_rounds
from .retargeting import FEET, HANDS, LimbTarget


class ScheduleError(ValueError):
    """The keyframes cannot be turned into a schedule (e.g. placing an object that is not held)."""

    code = -5  # RETARGETING_INFEASIBLE


_VERBS = {
    "pick": ("pick up", "pick", "grab", "lift", "take", "grasp", "hold", "retrieve"),
    "place": ("place", "put", "set down", "drop", "release", "load"),
    "push": ("push", "roll", "slide"),
    "step_on": ("step on", "step onto", "climb", "stand on"),
}


_LIFT_VERBS = ("pick up", "lift", "take", "retrieve", "carry")


def lifts(prompt: str) -> bool:
    """Whether a prompt asks to lift what it grasps ("pick up the box"), not only to grab it
    ("grab the basket": the plan's last subtask then lifts it only ``Timing.final_lift``)."""
    text = prompt.lower()
    return any(re.search(rf"\b{re.escape(v)}\b", text) for v in _LIFT_VERBS)


def actions_of(prompt: str) -> list[str]:
    """Actions a prompt asks for, in the order they appear ("step on the box and grab ..." ->
    ["step_on", "pick"])."""
    text = prompt.lower()
    found = []
    for action, verbs in _VERBS.items():
        positions = [m.start() for v in verbs for m in re.finditer(rf"\b{re.escape(v)}\b", text)]
        if positions:
            found.append((min(positions), action))
    return [a for _, a in sorted(found)]


@dataclass(frozen=True)
class Timing:
    """Phase durations and step limits. The defaults are those of the hand-written S1/S2 fixtures
    (src/lomanip_to/config/s1_basket.yaml, s2_trolley.yaml), on which the TO converges: 0.5 s
    single support, 0.2 s double support, 8 steps carrying S1's box about 1.3 m (0.32 m a step),
    0.8 s + 0.4 s for each step up onto the box, 1 s to stand up after letting go."""

    step: float = 0.5               # single support per step (s)
    double_support: float = 0.2     # between steps
    max_step_length: float = 0.35   # m per step of one foot (horizontal)
    step_up: float = 0.8            # single support of a step onto another surface (s)
    step_up_double_support: float = 0.4   # double support after it
    reach: float = 0.8              # move the hands to the object
    # a reach to a hand target higher than ``reach_shoulder_height`` above the soles lasts longer by
    # the excess over ``reach_overhead_speed`` (0 = off). Why: S1's grab (the basket 1.3 m above the
    # soles on the box) in 0.8 s turned the arms up to 0.86 rad per 0.2 s knot interval; between the
    # knots the hands cut 5-7 cm through the shelf's leg and top board, which the TO's collision rows
    # (at the knots) do not see, and executed the wrist caught on the shelf (session 55)
    reach_shoulder_height: float = 1.0
    reach_overhead_speed: float = 0.3   # m/s
    grasp: float = 0.4              # hands in contact before the object moves
    manipulate: float = 0.8         # lift / lower
    release: float = 0.4            # hands still in contact after the object rests
    retract: float = 1.0            # hands back, double support (discretize.STAND_UP_TIME)
    weight_shift: float = 0.4       # double support before the first step of a subtask (it starts at rest)
    # double support holding a lifted object before the carry's first step (0 = the lift is the
    # weight shift). Why: S1's plans stood up from the squat and stepped at once; in that first step
    # they swung the box up to 1.0-1.3 m and rolled the pelvis 0.4-0.8 rad (docs/to.md, session 21).
    # 0.6 s (0.4 before session 44): with ``manipulate`` the lift is 1.4 s, the S1 fixture's since
    # session 42; S1 from prompts with 0.4 s dropped the box in the lift when executed, with 0.6 s it
    # carried it two steps (docs/planner_s1.md, session 44)
    lift_settle: float = 0.6
    # m: the plan's last subtask lifts what it grabs by this much (a placement goal above where the
    # object rests, after ``manipulate``) and holds it to the end; 0 = it ends holding the object where
    # it is. Why: S1's success test needs the basket 10 cm above its shelf (lomanip_sim.task_success)
    final_lift: float = 0.15


@dataclass
class Stance:
    """Where the feet are: world positions of the sole centres and what they stand on."""

    left: np.ndarray
    right: np.ndarray
    left_surface: str = FLOOR
    right_surface: str = FLOOR
    #: foot -> rad about z where its sole points, once a walk placed it (else the pair's heading)
    headings: dict = field(default_factory=dict)

    def foot(self, limb: str) -> np.ndarray:
        return self.left if limb == "left_foot" else self.right

    def heading(self, limb: str) -> float:
        if limb in self.headings:
            return float(self.headings[limb])
        return _stance_yaw(self.left, self.right)

    def surface(self, limb: str) -> str:
        return self.left_surface if limb == "left_foot" else self.right_surface


@dataclass
class SubtaskKeyframe:
    """A retargeted keyframe with its contacts (world frame) and the subtask it belongs to."""

    index: int
    prompt: str
    qpos: np.ndarray                     # 36: base position, quaternion (w, x, y, z), 29 joints
    contacts: list[LimbTarget]
    rolling_objects: frozenset = frozenset()   # ids of wheeled objects (push -> ``rolling``)
    placement: PlacementGoal | None = None
    reference_object_id: str = ""
    retarget: object | None = None       # the RetargetResult (residuals, limits, timing) it came from
    push_feet: list = field(default_factory=list)   # push: where the feet end (the object moved with them)
    load_balance: object | None = None   # keyframes.LoadBalance of a keyframe whose hands hold a weight


@dataclass
class Schedule:
    phases: list[ContactPhase] = field(default_factory=list)
    keyframes: list[Keyframe] = field(default_factory=list)
    placement_goals: list[PlacementGoal] = field(default_factory=list)

    @property
    def duration(self) -> float:
        return self.phases[-1].end if self.phases else 0.0


def _stance_yaw(left: np.ndarray, right: np.ndarray) -> float:
    lat = np.asarray(left, float)[:2] - np.asarray(right, float)[:2]
    return math.atan2(lat[1], lat[0]) - math.pi / 2


#: least distance of an intermediate foothold from an object's footprint (m): half the G1 foot's
#: length plus a margin (the route keeps the mid-feet point clear, but near an object the route's
#: clearance shrinks and a foot beside it may land on the footprint: S2's walk round the trolley)
FOOTHOLD_CLEARANCE = 0.12


def _clear_of(p: np.ndarray, obstacles: list[Footprint], clearance: float = FOOTHOLD_CLEARANCE) -> np.ndarray:
    """``p`` (x, y) pushed out of every footprint closer than ``clearance``, across its nearest side."""
    p = np.asarray(p, float).copy()
    for _ in range(3):
        moved = False
        for fp in obstacles:
            if fp.distance(p) >= clearance - 1e-9:
                continue
            c, s = math.cos(fp.yaw), math.sin(fp.yaw)
            d = p - np.asarray(fp.centre, float)
            loc = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])
            half = np.asarray(fp.half, float) + clearance
            inside = np.abs(loc) <= half
            if inside.all():   # across the side it is nearest to
                k = int(np.argmin(half - np.abs(loc)))
                loc[k] = math.copysign(half[k], loc[k] if loc[k] else 1.0)
            p = np.asarray(fp.centre, float) + np.array([c * loc[0] - s * loc[1], s * loc[0] + c * loc[1]])
            moved = True
        if not moved:
            break
    return p


class _Builder:
    def __init__(self, stance: Stance, timing: Timing, objects: list | None = None) -> None:
        self.t = 0.0
        self.stance = stance
        self.timing = timing
        self.held: dict[str, ContactSpec] = {}      # hand -> contact it holds
        self.carried: set[str] = set()              # objects moving with the hands
        self.resting_on: dict[str, str] = {}        # placed object -> what it was placed on
        self.phases: list[ContactPhase] = []
        self.objects = {o.id: o for o in (objects or [])}
        self.footprints: dict[str, Footprint] = {o.id: footprint_of(o, o.position, o.rpy())
                                                 for o in self.objects.values() if o.primitives}
        # object -> (position, yaw) where it stands now: its scene pose, or where a place or push left it
        self.poses: dict[str, tuple[np.ndarray, float]] = {o.id: (np.asarray(o.position, float), float(o.rpy()[2]))
                                                           for o in self.objects.values()}

    def moved(self, oid: str, position, yaw: float) -> None:
        """An object now stands at its placement goal (its footprint moves with it)."""
        o = self.objects.get(oid)
        if o is not None and o.primitives:
            self.footprints[oid] = footprint_of(o, position, (0.0, 0.0, yaw))
        if o is not None:
            self.poses[oid] = (np.asarray(position, float), float(yaw))

    def support_under(self, oid: str, position) -> str:
        """What an object placed at ``position`` (its origin, kept level) rests on: the scene object
        with the highest level primitive whose top is at the placed bottom and holds the point, else
        the floor.  Per primitive: a trolley's top is its handle, its deck is lower (taken whole,
        S2's box on the deck rested on the floor in the schedule).  Supports are taken where the
        scene has them (they have not moved before a place in S1/S2); simplification (named)."""
        o = self.objects.get(oid)
        if o is None or not o.primitives:
            return FLOOR
        bottom = float(position[2]) + o.bottom_z()
        best, best_top = FLOOR, 0.02
        for sid, s in self.objects.items():
            if sid == oid or not s.primitives:
                continue
            for c, R, half in obj_prims_world(s):
                top = float(c[2] + half[2])
                if (abs(R[2, 2] - 1.0) < 1e-6 and abs(top - bottom) < 0.03 and top > best_top
                        and outside_top(position, c, R, half) <= 0.0):
                    best, best_top = sid, top
        return best

    def _obstacles(self, targets: dict[str, tuple[np.ndarray, str]]) -> list[Footprint]:
        """Footprints of the objects the robot neither holds nor stands or steps on."""
        held = self._held_objects()
        onto = {targets[f][1] for f in targets} | {self.stance.surface(f) for f in FEET}
        return [fp for oid, fp in self.footprints.items() if oid not in held and oid not in onto]

    def _held_objects(self) -> set[str]:
        return {c.object_id for c in self.held.values()} | self.carried

    def _foothold_obstacles(self, foot: str) -> list[Footprint]:
        """Footprints an intermediate foothold of ``foot`` keeps clear of: every object the hands do
        not hold but the surface the foot stands on, the one it is about to step onto included (the
        route may end on S1's box; a floor step halfway there put the right sole's toe 12 cm under
        the box, and the generated S1's TO stopped at its cap on that foothold, session 44)."""
        held = self._held_objects()
        return [fp for oid, fp in self.footprints.items() if oid not in held and oid != self.stance.surface(foot)]

    def _route(self, targets: dict[str, tuple[np.ndarray, str]]) -> np.ndarray:
        """Route of the mid-feet point to the targets' round the objects in the way."""
        a = 0.5 * (self.stance.left + self.stance.right)
        b = 0.5 * (targets.get("left_foot", (self.stance.left,))[0] + targets.get("right_foot", (self.stance.right,))[0])
        return shortest_route(a[:2], b[:2], self._obstacles(targets))

    def _feet(self, only: str | None = None) -> dict[str, ContactSpec]:
        out = {}
        for f in FEET:
            if only is None or f == only:
                out[f] = ContactSpec(f, self.stance.surface(f), tuple(self.stance.foot(f)), (0.0, 0.0, 1.0),
                                     self.stance.heading(f))
        return out

    def add(self, duration: float, subtask: int, kind: str = STANCE, stance_foot: str | None = None,
            hands: dict[str, ContactSpec] | None = None, objects: dict[str, ObjectMotion] | None = None) -> None:
        contacts = self._feet(stance_foot if kind == WALKING else None)
        contacts.update(hands if hands is not None else self.held)
        self.phases.append(ContactPhase(start=self.t, end=self.t + duration, phase_type=kind, subtask_index=subtask,
                                        contacts=contacts, objects=dict(objects if objects is not None else
                                                                        {o: ObjectMotion("free") for o in self.carried})))
        self.t += duration

    def reach_time(self, hands: dict) -> float:
        """Duration of a reach to ``hands`` (limb -> ContactSpec): Timing.reach, longer for a target
        above the shoulders (Timing.reach_shoulder_height above the lower sole)."""
        tm = self.timing
        if tm.reach_overhead_speed <= 0 or not hands:
            return tm.reach
        soles = min(float(self.stance.left[2]), float(self.stance.right[2]))
        rise = max(float(c.position[2]) for c in hands.values()) - soles - tm.reach_shoulder_height
        return tm.reach + max(rise, 0.0) / tm.reach_overhead_speed

    def walk_to(self, targets: dict[str, tuple[np.ndarray, str]], subtask: int,
                objects: dict[str, ObjectMotion] | None = None) -> None:
        """Footsteps from the current stance to ``targets`` (foot -> (position, surface)).

        The number of steps follows the horizontal distance (``max_step_length``); a foot that
        changes surface (onto S1's box) does so in its last step, a longer one (``step_up``)."""
        tm = self.timing
        moves = {f: float(np.linalg.norm(targets[f][0][:2] - self.stance.foot(f)[:2])) for f in targets}
        moving = [f for f in FEET if f in targets and (moves[f] > 0.02 or targets[f][1] != self.stance.surface(f)
                                                       or abs(targets[f][0][2] - self.stance.foot(f)[2]) > 0.02)]
        if not moving:
            return
        if not self.phases or self.phases[-1].subtask_index != subtask:
            # the TO solves subtask by subtask, each starting at rest: moving the CoM over the stance
            # foot takes a double support before the first swing (without it the TO whipped the hips)
            self.add(tm.weight_shift, subtask, objects=objects)
        route = self._route(targets)
        n = max(1, math.ceil((max([moves[f] for f in moving] + [route_length(route)]) - 1e-6) / tm.max_step_length))
        starts = {f: self.stance.foot(f).copy() for f in moving}
        half_width = 0.5 * float(np.linalg.norm(self.stance.left[:2] - self.stance.right[:2]))
        yaw0 = _stance_yaw(self.stance.left, self.stance.right)
        end = {f: targets[f][0] if f in targets else self.stance.foot(f) for f in FEET}
        yaw1 = yaw0 + math.remainder(_stance_yaw(end["left_foot"], end["right_foot"]) - yaw0, 2 * math.pi)
        # lead with the foot that has further to go; alternate feet
        first = max(moving, key=lambda f: moves[f])
        if len(moving) == 2 and len(route) == 2:   # rounds of steps a leg can make (lomanip_planner.footsteps)
            walk = Walk(route, starts, end, yaw0, yaw1)
            rounds = plan_rounds(walk, first, StepLimits(length=tm.max_step_length), n)
        else:
            walk, rounds = None, [(s, first) for s in uniform_rounds(n)]
        # a long walk far off the robot's heading turns to walk forwards (lomanip_to.route.turns): the
        # footholds lie beside the route, across the heading the TO's nominal turns with
        turning = turns(route, yaw0, yaw1)
        n = len(rounds)
        for i, (s, lead) in enumerate(rounds, start=1):
            for f in [lead, *[g for g in moving if g != lead]]:
                other = "right_foot" if f == "left_foot" else "left_foot"
                up = i == n and (targets[f][1] != self.stance.surface(f)
                                 or abs(targets[f][0][2] - starts[f][2]) > 0.02)
                self.add(tm.step_up if up else tm.step, subtask, WALKING, stance_foot=other, objects=objects)
                pos = starts[f] + s * (targets[f][0] - starts[f])
                heading = yaw1
                if i < n and walk is not None:
                    pos[:2], heading = walk.foot(f, s), walk.heading(s)
                elif i < n:
                    heading = walking_heading(route, s, yaw0, yaw1) if turning else yaw0 + s * (yaw1 - yaw0)
                    if turning or len(route) > 2:   # beside the route
                        side = 1.0 if f == "left_foot" else -1.0
                        pos[:2] = point_along(route, s) + side * half_width * np.array([-math.sin(heading),
                                                                                        math.cos(heading)])
                self.stance.headings[f] = float(heading)
                surface = targets[f][1] if i == n else self.stance.surface(f)
                if i < n:   # intermediate footholds stay on the surface the foot started on, off objects
                    pos[2] = starts[f][2]
                    pos[:2] = _clear_of(pos[:2], self._foothold_obstacles(f))
                if f == "left_foot":
                    self.stance.left, self.stance.left_surface = pos, surface
                else:
                    self.stance.right, self.stance.right_surface = pos, surface
                self.add(tm.step_up_double_support if up else tm.double_support, subtask, objects=objects)


def plan_schedule(initial: Stance, subtasks: list[SubtaskKeyframe], timing: Timing = Timing(),
                  objects: list | None = None) -> Schedule:
    """Phases, keyframes (with their times) and placement goals for the TO.  ``objects`` (scene
    objects) are walked round; without them the footsteps go straight."""
    from lomanip_sim import frames

    b = _Builder(Stance(initial.left.copy(), initial.right.copy(), initial.left_surface, initial.right_surface), timing,
                 objects)
    out = Schedule()
    tm = timing
    lift_next: str | None = None
    for pos, sk in enumerate(subtasks):
        actions = actions_of(sk.prompt)
        if not actions:
            raise ScheduleError(f"subtask {sk.index} ({sk.prompt!r}): no known action (pick, place, push, step on)")
        if lift_next is not None:
            # the previous subtask ended with the object grasped, at rest; its lift opens this subtask
            # (as in the fixtures): the TO's segment boundary is then at the grasp, not mid-lift, and
            # the lift doubles as the weight shift before the first step
            b.carried.add(lift_next)
            b.add(tm.manipulate, sk.index)
            if tm.lift_settle > 0:
                b.add(tm.lift_settle, sk.index)
            lift_next = None
        feet = {c.limb: (np.asarray(c.position, float), c.object_id) for c in sk.contacts if c.limb in FEET}
        hands = {c.limb: ContactSpec(c.limb, c.object_id, tuple(np.asarray(c.position, float)),
                                     tuple(np.asarray(c.normal, float))) for c in sk.contacts if c.limb in HANDS}
        kf_time = None
        if "push" in actions:
            if not hands:
                raise ScheduleError(f"subtask {sk.index} ({sk.prompt!r}): push without a hand contact")
            target = next(iter(hands.values())).object_id
            b.walk_to(feet, sk.index)                        # up to the object (keyframe stance)
            b.add(b.reach_time(hands), sk.index, hands=dict(b.held))
            b.held = dict(hands)
            b.add(tm.grasp, sk.index, objects={})
            kf_time = b.t
            mode = "rolling" if target in sk.rolling_objects else "supported"
            after = {c.limb: (np.asarray(c.position, float), c.object_id) for c in sk.push_feet}
            riding = {o: ObjectMotion("attached", attached_to=target) for o, sup in b.resting_on.items() if sup == target}
            b.walk_to(after, sk.index, objects={target: ObjectMotion(mode), **riding})   # the push itself
            if sk.placement is not None and sk.placement.object_id == target:
                out.placement_goals.append(PlacementGoal(target, tuple(sk.placement.position), sk.placement.yaw,
                                                         time=b.t, weight=sk.placement.weight))
                b.moved(target, sk.placement.position, sk.placement.yaw)
            b.add(tm.release, sk.index, objects={})
            b.held = {}
            b.add(tm.retract, sk.index, objects={})
        else:
            b.walk_to(feet, sk.index)
            if "pick" in actions:
                if not hands:
                    raise ScheduleError(f"subtask {sk.index} ({sk.prompt!r}): pick without a hand contact")
                obj = next(iter(hands.values())).object_id
                b.add(b.reach_time(hands), sk.index, hands=dict(b.held))
                b.held.update(hands)
                b.add(tm.grasp, sk.index)
                kf_time = b.t
                if "place" in actions or (pos == len(subtasks) - 1 and lifts(sk.prompt)):
                    b.carried.add(obj)             # lifted here: placed in this subtask, or the plan's end
                    b.add(tm.manipulate, sk.index)
                elif pos < len(subtasks) - 1:
                    lift_next = obj                # the next subtask opens with the lift
                elif tm.final_lift > 0 and obj in b.objects:   # the plan's last grab takes it off its support
                    at, yaw = b.poses[obj]
                    b.carried.add(obj)
                    b.add(tm.manipulate, sk.index)
                    goal = at + [0.0, 0.0, tm.final_lift]
                    out.placement_goals.append(PlacementGoal(obj, tuple(float(v) for v in goal), yaw, time=b.t))
            if "place" in actions:
                if not b.carried:
                    raise ScheduleError(f"subtask {sk.index} ({sk.prompt!r}): nothing is held to place")
                if sk.placement is None:
                    raise ScheduleError(f"subtask {sk.index} ({sk.prompt!r}): placement needs a goal (object, position, yaw)")
                if sk.placement.object_id not in b.carried:
                    raise ScheduleError(f"subtask {sk.index}: {sk.placement.object_id!r} is not the held object")
                b.add(tm.manipulate, sk.index)
                kf_time = b.t
                out.placement_goals.append(PlacementGoal(sk.placement.object_id, tuple(sk.placement.position),
                                                         sk.placement.yaw, time=b.t, weight=sk.placement.weight))
                placed = sk.placement.object_id
                b.carried.discard(placed)
                b.moved(placed, sk.placement.position, sk.placement.yaw)
                # set down, it rests on its support under the hands' release (corner forces,
                # friction; the TO's `supported`) until the subtask ends at rest. Why: as `fixed`
                # from the place knot on, S1's guide could not meet the place (box kinematics 5e-2)
                # and its path sank into the floor; supported, the same guide converged
                # On another object's top (S2's box on the trolley's deck) it is static from the
                # place knot on instead, as in the S2 fixture the TO converges on: the TO finds the
                # top under it there (its `supported` mode takes an object's highest top)
                sup = b.support_under(placed, sk.placement.position)
                b.resting_on[placed] = sup
                resting = {o: ObjectMotion("free") for o in b.carried}
                if sup == FLOOR:
                    resting[placed] = ObjectMotion("supported", support=sup)
                b.add(tm.release, sk.index, objects=resting)
                b.held = {h: c for h, c in b.held.items() if c.object_id != placed}
                b.add(tm.retract, sk.index, objects=resting)
            if kf_time is None:          # step on only
                b.add(tm.retract, sk.index)
                kf_time = b.t
        q = np.asarray(sk.qpos, float)
        mid = np.mean([b.stance.left, b.stance.right], axis=0)
        out.keyframes.append(Keyframe(
            subtask_index=sk.index, base_position=tuple(q[:3]), base_quat_xyzw=tuple(frames.wxyz_to_xyzw(q[3:7])),
            joints=tuple(q[7:]), contacts=list(hands.values()), desired_foot_xy=(float(mid[0]), float(mid[1])),
            reference_object_id=sk.reference_object_id, prompt=sk.prompt, time=kf_time))
    b.add(tm.retract, subtasks[-1].index if subtasks else 0)   # settle at the end
    out.phases = b.phases
    return out
