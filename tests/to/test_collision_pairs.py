"""The minimal collision set (ProblemData._choose_pairs) holds every robot sphere / static object
primitive pair that comes within ``pair_prefilter`` at ANY knot of the warm start."""
import numpy as np

from lomanip_to.discretize import ProblemData, box_distances, obj_prims_world
from lomanip_to.fixtures import load_problem


def test_s1_pairs_cover_every_knot_of_the_warm_start(g1):
    prob = load_problem("s1_basket", model=g1)
    data = ProblemData(prob, g1)
    groups = set(prob.options.collision_groups)
    spheres = [i for i, s in enumerate(g1.spheres) if s.group in groups]
    cs = np.array([g1.numeric(x)["spheres"] for x in data.x_guess])   # K x S x 3
    thr = data.w["pair_prefilter"]
    chosen = set(data.pairs)
    missed = []
    for o in prob.objects:
        if o.id in data.moving:
            continue
        for pi, prim in enumerate(obj_prims_world(o)):
            for s in spheres:
                if box_distances(cs[:, s, :], *prim, g1.spheres[s].radius).min() < thr and (s, (o.id, pi)) not in chosen:
                    missed.append((g1.spheres[s].group, o.id, pi))
    # with every 5th knot sampled, the left hand's pass by the shelf's middle board (0.21 m away at
    # 15.8 s, in the step onto the box) had no pair, and a plan put the hand 48 mm into it
    assert not missed
    assert any(s_pair[1] == ("shelf", 5) and g1.spheres[s_pair[0]].group == "left_hand" for s_pair in chosen)
