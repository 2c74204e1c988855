"""Subtask prompts: the paper's LDM prompt template and a small parser of who touches what.

Paper Sec. III-A1: each subtask prompt P_i becomes
  "A scene of a person {predicate}+ing {subtask prompt without predicate}. The person has dark hair
   and is wearing casual clothes such a shirt, jeans, and sneakers"
(the wording, including "such a shirt", is the paper's). :func:`generation_prompt` builds exactly
that; only the leading predicate is turned into its -ing form, as the paper states.

The parser turns "step on the box and grab the basket" into interactions
[(step, feet, box), (grab, hands, basket)] plus reference objects ("from the table", "next to the
shelf"). Perception uses it to know which limbs are expected on which object, and the synthetic
image generator to compose a demonstration. It is a deliberately small, explicit grammar (verb
lexicon + "the <noun>"), not a language model; prompts outside it give a clear INVALID_REQUEST.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

from .errors import INVALID_REQUEST, UNKNOWN_OBJECT, PerceptionError, subtask_label

APPEARANCE = ("The person has dark hair and is wearing casual clothes such a shirt, jeans, and sneakers")
TEMPLATE = "A scene of a person {gerund} {rest}. " + APPEARANCE

HANDS = ("left_hand", "right_hand")
FEET = ("left_foot", "right_foot")

#: predicate -> (action, limbs). Longest match wins, so "pick up" beats "pick".
PREDICATES: dict[str, tuple[str, tuple[str, ...]]] = {
    "pick up": ("pick", HANDS), "lift": ("pick", HANDS), "take": ("pick", HANDS),
    "carry": ("pick", HANDS), "hold": ("pick", HANDS), "move": ("pick", HANDS),
    "place": ("place", HANDS), "put": ("place", HANDS), "put down": ("place", HANDS),
    "set": ("place", HANDS), "set down": ("place", HANDS), "drop": ("place", HANDS),
    "grab": ("grab", HANDS), "grasp": ("grab", HANDS), "reach for": ("grab", HANDS),
    "retrieve": ("grab", HANDS), "get": ("grab", HANDS),
    "push": ("push", HANDS), "pull": ("push", HANDS), "shove": ("push", HANDS),
    "step on": ("step", FEET), "step onto": ("step", FEET), "stand on": ("step", FEET),
    "climb on": ("step", FEET), "climb onto": ("step", FEET), "get on": ("step", FEET),
}
_IRREGULAR_GERUNDS = {"get": "getting", "put": "putting", "set": "setting", "grab": "grabbing",
                      "step": "stepping", "drop": "dropping", "shove": "shoving", "stand": "standing"}
DETERMINERS = {"the", "a", "an", "this", "that", "its", "my", "your"}
#: words that end a noun phrase (prepositions, adverbs)
STOP_WORDS = {"from", "on", "onto", "to", "next", "near", "beside", "by", "forward", "forwards", "back",
              "backward", "backwards", "with", "into", "in", "and", "off", "up", "down", "away", "toward",
              "towards", "over", "under", "at", "then", "of", "across", "along", "behind", "closer"}
REFERENCE_PREPOSITIONS = ("next to", "from", "onto", "on top of", "on", "into", "near", "beside", "to",
                          "in front of", "under", "behind")
#: places that are not scene objects
LOCATION_WORDS = {"floor", "ground", "room", "left", "right", "side", "front", "back", "corner", "place",
                  "position", "goal", "target", "way", "it", "them", "there", "here", "wall", "top"}
#: open-vocabulary synonyms -> the scene's class names
SYNONYMS = {"crate": "box", "carton": "box", "cardboard": "box", "package": "box", "parcel": "box",
            "cart": "trolley", "handcart": "trolley", "desk": "table", "bench": "table",
            "shelves": "shelf", "shelving": "shelf", "rack": "shelf", "bookshelf": "shelf", "cupboard": "shelf",
            "bin": "basket", "hamper": "basket"}


@dataclass(frozen=True)
class Interaction:
    """One verb clause: ``limbs`` touch an object of ``object_class`` doing ``action``."""

    action: str  # pick | place | grab | push | step
    predicate: str
    limbs: tuple[str, ...]
    object_class: str
    object_phrase: str


@dataclass(frozen=True)
class Subtask:
    """A parsed subtask prompt."""

    index: int
    prompt: str
    predicate: str
    rest: str
    interactions: tuple[Interaction, ...]
    references: tuple[tuple[str, str], ...] = field(default=())  # (preposition, class)

    @property
    def label(self) -> str:
        return subtask_label(self.index, self.prompt)

    @property
    def object_classes(self) -> list[str]:
        out = []
        for c in [i.object_class for i in self.interactions] + [c for _, c in self.references]:
            if c not in out:
                out.append(c)
        return out


def normalise(prompt: str) -> str:
    return re.sub(r"\s+", " ", prompt.strip().rstrip(".!").strip()).lower()


def gerund(predicate: str) -> str:
    """'pick up' -> 'picking up', 'place' -> 'placing', 'step on' -> 'stepping on'."""
    words = predicate.split(" ")
    verb = words[0]
    if verb in _IRREGULAR_GERUNDS:
        ing = _IRREGULAR_GERUNDS[verb]
    elif verb.endswith("ie"):
        ing = verb[:-2] + "ying"
    elif verb.endswith("e") and not verb.endswith("ee"):
        ing = verb[:-1] + "ing"
    else:
        ing = verb + "ing"
    return " ".join([ing] + words[1:])


def split_predicate(prompt: str) -> tuple[str, str]:
    """Leading predicate and the rest of a normalised prompt; ('', prompt) if none is known."""
    text = normalise(prompt)
    for pred in sorted(PREDICATES, key=len, reverse=True):
        if text == pred or text.startswith(pred + " "):
            return pred, text[len(pred):].strip()
    return "", text


def generation_prompt(prompt: str) -> str:
    """The paper's text-to-image prompt for one subtask prompt."""
    pred, rest = split_predicate(prompt)
    if not pred:  # not in the lexicon: take the first word as the predicate, as the paper's rule does
        words = normalise(prompt).split(" ")
        pred, rest = words[0], " ".join(words[1:])
    return TEMPLATE.format(gerund=gerund(pred), rest=rest).replace("  ", " ")


def _noun_phrase(words: list[str]) -> tuple[str, str, int]:
    """(head noun, phrase, words consumed) of 'the big box from ...' -> ('box', 'the big box', 3)."""
    i = 0
    phrase = []
    while i < len(words) and words[i] in DETERMINERS:
        phrase.append(words[i])
        i += 1
    body = []
    while i < len(words) and words[i] not in STOP_WORDS:
        body.append(words[i])
        i += 1
    return (body[-1] if body else ""), " ".join(phrase + body), i


def _resolve_class(noun: str, known: set[str]) -> str:
    n = SYNONYMS.get(noun, noun)
    if n in known:
        return n
    if n.endswith("s") and n[:-1] in known:
        return n[:-1]
    return n


def parse_subtask(index: int, prompt: str, known_classes: set[str] | list[str]) -> Subtask:
    """Parse one prompt against the classes present in the scene.

    Raises PerceptionError(INVALID_REQUEST) for an empty prompt or one with no known action, and
    PerceptionError(UNKNOWN_OBJECT) when the prompt names an object the scene does not contain.
    """
    known = set(known_classes)
    text = normalise(prompt)
    label = subtask_label(index, prompt)
    if not text:
        raise PerceptionError(INVALID_REQUEST, f"{label}: empty prompt", index)
    pred, rest = split_predicate(text)
    if not pred:
        raise PerceptionError(INVALID_REQUEST, f"{label}: no known action; the prompt must start with one of: "
                              + ", ".join(sorted(PREDICATES)), index)  # fmt: skip
    # clauses: "<pred> <np> ... and <pred> <np> ..."
    clauses: list[tuple[str, str]] = [(pred, rest)]
    while True:
        p0, r0 = clauses[-1]
        m = re.search(r"\b(and|then|and then)\s+", r0)
        if not m:
            break
        tail = r0[m.end():]
        p1, r1 = split_predicate(tail)
        if not p1:
            break
        clauses[-1] = (p0, r0[:m.start()].strip())
        clauses.append((p1, r1))
    interactions, references = [], []
    for p, r in clauses:
        words = r.split(" ") if r else []
        noun, phrase, used = _noun_phrase(words)
        if not noun:
            raise PerceptionError(INVALID_REQUEST, f"{label}: '{p}' names no object", index)
        cls = _resolve_class(noun, known)
        if cls not in known:
            raise PerceptionError(UNKNOWN_OBJECT, f"{label}: no object of class {noun!r} in the scene "
                                  f"(scene has: {', '.join(sorted(known)) or 'nothing'})", index)  # fmt: skip
        action, limbs = PREDICATES[p]
        interactions.append(Interaction(action, p, limbs, cls, phrase))
        tail = " ".join(words[used:])
        for prep in sorted(REFERENCE_PREPOSITIONS, key=len, reverse=True):
            for m in re.finditer(rf"\b{prep}\s+", tail):
                rnoun, _, _ = _noun_phrase(tail[m.end():].split(" "))
                if not rnoun or not (set(tail[m.end():].split(" ")[:1]) & DETERMINERS):
                    continue
                if rnoun in LOCATION_WORDS:
                    continue
                rcls = _resolve_class(rnoun, known)
                if rcls not in known:
                    raise PerceptionError(UNKNOWN_OBJECT, f"{label}: no object of class {rnoun!r} in the scene "
                                          f"(scene has: {', '.join(sorted(known))})", index)  # fmt: skip
                if (prep, rcls) not in references and all(c != rcls for _, c in references):
                    references.append((prep, rcls))
    return Subtask(index, prompt, pred, rest, tuple(interactions), tuple(references))


def parse_prompts(prompts: list[str], known_classes) -> list[Subtask]:
    """Parse an ordered prompt list; raises PerceptionError(INVALID_REQUEST) if it is empty."""
    if not prompts:
        raise PerceptionError(INVALID_REQUEST, "empty prompt list: give at least one subtask prompt")
    return [parse_subtask(i, p, known_classes) for i, p in enumerate(prompts)]
