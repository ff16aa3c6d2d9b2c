"""What the app generates (app/generation.py)."""
import numpy as np
import pytest

import app.generation
from app.document import Document
from app.generation import GenerationSettings, drawn_cast, start_generation
from engine.poses import standing_pose_2d
from engine.storyboard import Keypose, Storyboard


def keyed(agents: str) -> Storyboard:
    sb = Document().storyboard
    pose = standing_pose_2d(sb.camera)
    sb.keyposes = [Keypose(a, 0, pose.copy(), np.ones(len(pose), bool)) for a in agents]
    return sb


@pytest.mark.parametrize("drawn, cast", [("AB", "AB"), ("A", "A"), ("B", "AB"), ("", "AB")])
def test_the_last_people_nothing_is_drawn_for_are_left_out(drawn, cast):
    assert [a.id for a in drawn_cast(keyed(drawn)).agents] == list(cast)


def test_a_solo_scene_in_a_new_document_asks_for_its_one_person(monkeypatch):
    """The document's second person, never drawn, wandered into a solo lift when animated."""
    import engine.sampling.sampler
    asked = []

    def sample(bundle, request, checkpoint):
        asked.append(request)
        yield from ()

    monkeypatch.setattr(app.generation, "_bundle", lambda: None)
    monkeypatch.setattr(engine.sampling.sampler, "sample", sample)
    list(start_generation(keyed("A"), GenerationSettings(steps=2)))
    assert [a.id for a in asked[0].storyboard.agents] == ["A"]
