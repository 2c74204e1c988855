"""scenario: defaults and paper grids come from scenarios.yaml; bad input gives one-line errors."""

import pytest

from lomanip_sim.scenario import (
    S1BasketParams,
    S2TrolleyParams,
    ScenarioError,
    load_grid,
    load_scenario,
    parse_overrides_yaml,
    scenario_names,
)


def _one_line(e: pytest.ExceptionInfo) -> str:
    msg = str(e.value)
    assert "\n" not in msg
    return msg


def test_defaults_load():
    assert scenario_names() == ["s1_basket", "s2_trolley"]
    s1 = load_scenario("s1_basket")
    assert isinstance(s1, S1BasketParams) and s1.box_mass == 2.5 and s1.timestep <= 0.002
    s2 = load_scenario("s2_trolley", {"box_mass": 3.3, "trolley_yaw": 0.2})
    assert isinstance(s2, S2TrolleyParams) and s2.box_mass == 3.3 and s2.trolley_yaw == 0.2
    assert (s2.camera_width, s2.camera_height) == (640, 480)


def test_paper_grids_from_yaml():
    g1 = load_grid("s1_basket")
    assert sorted({(p.box_mass, p.box_yaw) for p in g1}) == sorted(
        (m, y) for m in (2.5, 5.0) for y in (0.0, 0.6, 1.2)
    )
    g2 = load_grid("s2_trolley")
    assert len(g2) == 15
    assert {p.box_mass for p in g2} == {2.5, 5.0, 7.5}
    assert {p.box_yaw for p in g2} == {0.0, 0.6, -0.6, 1.2, -1.2}


def test_unknown_scenario():
    with pytest.raises(ScenarioError) as e:
        load_scenario("s3_kitchen")
    msg = _one_line(e)
    assert "s3_kitchen" in msg and "s1_basket" in msg and "s2_trolley" in msg


@pytest.mark.parametrize("key", ["box_mass", "basket_mass"])
@pytest.mark.parametrize("value", [-1.0, 0.0])
def test_non_positive_mass(key, value):
    with pytest.raises(ScenarioError) as e:
        load_scenario("s1_basket", {key: value})
    assert key in _one_line(e) and "> 0" in str(e.value)


def test_unknown_key_and_wrong_types():
    with pytest.raises(ScenarioError) as e:
        load_scenario("s2_trolley", {"box_colour": "red"})
    assert "box_colour" in _one_line(e)
    with pytest.raises(ScenarioError) as e:
        load_scenario("s2_trolley", {"box_size": [0.3, 0.3]})
    assert "3 numbers" in _one_line(e)
    with pytest.raises(ScenarioError) as e:
        load_scenario("s2_trolley", {"box_mass": "heavy"})
    assert "number" in _one_line(e)
    with pytest.raises(ScenarioError):
        load_scenario("s1_basket", {"camera_width": 640.5})
    with pytest.raises(ScenarioError):
        load_scenario("s1_basket", overrides=[("box_mass", 2.0)])  # type: ignore[arg-type]


def test_malformed_yaml_names_file_and_line(tmp_path):
    bad = tmp_path / "broken.yaml"
    bad.write_text("scenarios:\n  s1_basket:\n    parameters: {box_mass: 2.5\n    grid: [\n")
    with pytest.raises(ScenarioError) as e:
        load_scenario("s1_basket", path=bad)
    msg = _one_line(e)
    assert "broken.yaml" in msg and "line" in msg


def test_bad_value_in_file_is_reported(tmp_path):
    f = tmp_path / "neg.yaml"
    f.write_text("scenarios:\n  s1_basket:\n    parameters: {box_mass: -2}\n")
    with pytest.raises(ScenarioError) as e:
        load_scenario("s1_basket", path=f)
    assert "box_mass" in _one_line(e)


def test_yaml_round_trip_and_overrides_parser():
    p = load_scenario("s1_basket", parse_overrides_yaml("{box_mass: 5.0, box_yaw: 0.6}"))
    assert (p.box_mass, p.box_yaw) == (5.0, 0.6)
    import yaml

    d = yaml.safe_load(p.to_yaml())
    assert d["scenario"] == "s1_basket" and d["box_mass"] == 5.0
    assert load_scenario("s1_basket", {k: v for k, v in d.items() if k != "scenario"}) == p
    assert parse_overrides_yaml("") == {}
    with pytest.raises(ScenarioError):
        parse_overrides_yaml("[1, 2]")
