"""One strict reading of storyboards: whatever a careless or hostile file holds, loading it ends
in a storyboard whose controls can be built, or in a one-line StoryboardError, never another
exception (hypothesis mutates the bundled examples' JSON leaf by leaf)."""
import copy
import json
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from engine.controls import build_controls
from engine.request import Request
from engine.storyboard import Storyboard, StoryboardError

EXAMPLES = [json.loads(p.read_text()) for p in sorted(Path("resources/examples").glob("*.json"))]

junk = st.one_of(st.none(), st.booleans(), st.integers(min_value=-10 ** 420, max_value=10 ** 420),
                 st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=8),
                 st.lists(st.integers(-3, 200), max_size=3), st.just([]), st.just({}),
                 st.integers(0, 130).map(float), st.just([[0.1, 0.2]] * 30))


def _leaves(value, path=()):
    if isinstance(value, dict):
        for k, v in value.items():
            yield from _leaves(v, path + (k,))
    elif isinstance(value, list) and value and not all(isinstance(x, (int, float)) for x in value):
        for i, v in enumerate(value):
            yield from _leaves(v, path + (i,))
    yield path


def _set(doc, path, value):
    if not path:
        return value
    target = doc
    for key in path[:-1]:
        target = target[key]
    target[path[-1]] = value
    return doc


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(example=st.integers(0, len(EXAMPLES) - 1), picks=st.lists(st.tuples(st.integers(0, 10 ** 6), junk),
                                                                  min_size=1, max_size=3))
def test_any_mutation_loads_cleanly_or_fails_in_one_line(example, picks):
    doc = copy.deepcopy(EXAMPLES[example])
    for index, value in picks:
        leaves = list(_leaves(doc))
        doc = _set(doc, leaves[index % len(leaves)], copy.deepcopy(value))   # a shared value would make cycles
    try:
        text = json.dumps(doc)
    except (ValueError, OverflowError):
        return
    try:
        sb = Storyboard.from_json(text)
    except StoryboardError as e:
        assert "\n" not in str(e) and len(str(e)) < 400
        return
    build_controls(sb)
    Request.build(sb).for_model(4)
