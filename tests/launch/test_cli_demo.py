"""`lomanip demo` options: the main job plans and executes unless told not to."""

from lomanip_launch.cli import make_parser


def test_demo_executes_its_plan_by_default():
    args = make_parser().parse_args(["demo"])
    assert args.execute is True and args.task == "push_trolley"
    assert make_parser().parse_args(["demo", "--no-execute"]).execute is False
    assert make_parser().parse_args(["demo", "--execute"]).execute is True
