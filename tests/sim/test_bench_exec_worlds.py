"""tools/bench_exec.py --world: model-error worlds are parsed and checked before anything runs."""

import importlib.util
from pathlib import Path

import pytest

_PATH = Path(__file__).resolve().parents[2] / "tools" / "bench_exec.py"
_spec = importlib.util.spec_from_file_location("bench_exec_under_test", _PATH)
bench_exec = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench_exec)


def test_worlds_are_parsed_as_yaml_values():
    worlds = bench_exec.parse_worlds(["box_mass=3.0", "trolley_mass=6,trolley_position=[1.0, -0.9]"])
    assert worlds == [{"box_mass": 3.0}, {"trolley_mass": 6, "trolley_position": [1.0, -0.9]}]
    assert bench_exec.world_label(worlds[0]) == "box_mass=3.0"


@pytest.mark.parametrize("spec", ["box_mass", "=3.0", " =1"])
def test_a_malformed_world_is_refused(spec):
    with pytest.raises(ValueError, match="bad --world item"):
        bench_exec.parse_worlds([spec])


def test_world_keys_are_checked_against_the_scenario():
    bench_exec.check_worlds([{"box_mass": 2.0}, {"wheel_rolling_resistance": 3.0}], {"s2_trolley"})
    with pytest.raises(ValueError, match="unknown parameter 'box_mas'"):
        bench_exec.check_worlds([{"box_mas": 2.0}], {"s2_trolley"})
    with pytest.raises(ValueError, match="must be > 0"):
        bench_exec.check_worlds([{"box_mass": -1.0}], {"s1_basket"})
    with pytest.raises(ValueError, match="a finite number"):
        bench_exec.check_worlds(bench_exec.parse_worlds(["box_mass=3.0,"]), {"s2_trolley"})
    # a small case has no scenario: only the keys every scenario has (MuJoCo's options) apply
    bench_exec.check_worlds([{"friction_cone": "pyramidal", "impratio": 1.0}], {"case_lift_box"})
    with pytest.raises(ValueError, match="case_lift_box: .*unknown parameter 'box_mass'"):
        bench_exec.check_worlds([{"box_mass": 2.0}], {"case_lift_box"})
