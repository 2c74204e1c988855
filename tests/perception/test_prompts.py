"""Prompt template (paper Sec. III-A1, verbatim) and the subtask parser."""
from __future__ import annotations

import pytest

from lomanip_perception.errors import INVALID_REQUEST, UNKNOWN_OBJECT, PerceptionError
from lomanip_perception.prompts import gerund, generation_prompt, parse_prompts, parse_subtask, split_predicate

S1 = {"box", "shelf", "basket"}
S2 = {"box", "table", "trolley"}
APPEARANCE = ". The person has dark hair and is wearing casual clothes such a shirt, jeans, and sneakers"


@pytest.mark.parametrize("prompt,expected", [
    ("pick up the box", "A scene of a person picking up the box"),
    ("place the box next to the shelf", "A scene of a person placing the box next to the shelf"),
    ("step on the box and grab the basket", "A scene of a person stepping on the box and grab the basket"),
    ("push the trolley forward", "A scene of a person pushing the trolley forward"),
    ("Put the box on the trolley.", "A scene of a person putting the box on the trolley"),
])
def test_generation_prompt_is_the_papers_template(prompt, expected):
    assert generation_prompt(prompt) == expected + APPEARANCE


def test_gerunds():
    assert [gerund(p) for p in ("pick up", "place", "grab", "step on", "carry", "push", "lift", "tie")] == \
        ["picking up", "placing", "grabbing", "stepping on", "carrying", "pushing", "lifting", "tying"]


def test_longest_predicate_wins():
    assert split_predicate("put down the box") == ("put down", "the box")
    assert split_predicate("pick up the box") == ("pick up", "the box")


def test_parse_s1_and_s2():
    a, b, c = parse_prompts(["pick up the box", "place the box next to the shelf",
                             "step on the box and grab the basket"], S1)
    assert [(i.action, i.object_class, i.limbs) for i in a.interactions] == [("pick", "box", ("left_hand", "right_hand"))]
    assert b.interactions[0].action == "place" and b.references == (("next to", "shelf"),)
    assert [(i.action, i.object_class) for i in c.interactions] == [("step", "box"), ("grab", "basket")]
    assert c.interactions[0].limbs == ("left_foot", "right_foot")
    d, e, f = parse_prompts(["pick up the box from the table", "place the box on the trolley",
                             "push the trolley forward"], S2)
    assert d.references == (("from", "table"),) and d.object_classes == ["box", "table"]
    assert e.references == (("on", "trolley"),)
    assert f.interactions[0].action == "push" and f.interactions[0].object_class == "trolley"


def test_synonyms_adjectives_and_location_words():
    st = parse_subtask(0, "lift the red crate onto the cart", S2)
    assert st.interactions[0].object_class == "box" and st.references == (("onto", "trolley"),)
    st = parse_subtask(0, "place the box on the floor", S1)
    assert st.references == ()


def test_errors_name_the_subtask():
    with pytest.raises(PerceptionError) as e:
        parse_prompts(["pick up the box", "push the refrigerator"], S1)
    assert e.value.code == UNKNOWN_OBJECT and e.value.subtask_index == 1
    assert "subtask 1 'push the refrigerator'" in e.value.message and "refrigerator" in e.value.message
    with pytest.raises(PerceptionError) as e:
        parse_prompts(["place the box next to the fridge"], S1)
    assert e.value.code == UNKNOWN_OBJECT and "fridge" in e.value.message
    for bad in ("", "   ", "dance wildly", "pick up"):
        with pytest.raises(PerceptionError) as e:
            parse_prompts([bad], S1)
        assert e.value.code == INVALID_REQUEST and "subtask 0" in e.value.message
    with pytest.raises(PerceptionError) as e:
        parse_prompts([], S1)
    assert e.value.code == INVALID_REQUEST and "empty prompt list" in e.value.message
