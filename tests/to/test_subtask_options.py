"""Options.subtask_options: option overrides for the segments of one subtask."""
import pytest

from lomanip_to import solver
from lomanip_to.fixtures import load_problem
from lomanip_to.problem import INVALID_REQUEST, ProblemError, validate_problem


def _s1(g1, subtask_options):
    prob = load_problem("s1_basket", model=g1)
    prob.options = prob.options.replaced(subtask_options=subtask_options)
    return prob


def test_only_the_named_subtasks_segments_take_the_overrides(g1):
    prob = _s1(g1, {2: {"arm_body_self_pairs": True, "body_object_clearance": 0.02}})
    validate_problem(prob, g1)
    segs = solver.segments(prob)
    assert len(segs) == 3
    for t0, t1 in segs:
        sp = solver.segment_problem(prob, t0, t1, prob.initial_configuration, solver._initial_poses(prob))
        last = {ph.subtask_index for ph in sp.phases} == {2}
        assert sp.options.arm_body_self_pairs is last
        assert sp.options.body_object_clearance == (0.02 if last else 0.0)
    assert prob.options.arm_body_self_pairs is False  # the whole horizon keeps the problem's own


@pytest.mark.parametrize("over, says", [({7: {}}, "no subtask 7"), ({1: {"no_such_option": 1}}, "unknown option"),
                                        ({1: {"body_object_clearance": 0.5}}, "body_object_clearance must be"),
                                        ({1: "arm_body_self_pairs"}, "unknown option")])
def test_bad_overrides_are_refused_before_any_solve(g1, over, says):
    with pytest.raises(ProblemError) as e:
        validate_problem(_s1(g1, over), g1)
    assert e.value.code == INVALID_REQUEST and says in str(e.value)
