"""Takes in the app: each generation is kept, one variation of it chosen, saved beside the
storyboard and reopened without regenerating; earlier takes can be shown again."""
from PySide6.QtCore import Qt

from app.generation import GenerationSettings
from engine.takes import takes_path

from .fakes import FakeSampler, sample_storyboard


def generate(qtbot, window, seed: int) -> None:
    window.doc.set_settings(GenerationSettings(steps=3, seed=seed, variations=2))
    with qtbot.waitSignal(window.session.finished, timeout=10_000):
        window.generate()


def test_takes_are_kept_saved_and_reopened(qtbot, make_window, tmp_path, dialogs):
    sampler = FakeSampler()
    window = make_window(generate=sampler)
    window.doc.replace_storyboard(sample_storyboard(), None)
    generate(qtbot, window, seed=4)
    generate(qtbot, window, seed=9)
    doc, panel = window.doc, window.properties
    assert [t.seed for t in doc.takes] == [4, 9] and doc.take_index == 1
    assert panel.take.count() == 2 and panel.take.currentText().startswith("Take 2: seed 9")
    # Keep the second variation of take 2, with the keyboard on the Show list.
    panel.variation.setFocus()
    qtbot.keyClick(panel.variation, Qt.Key_Down)
    assert doc.variation == 1 and doc.takes[1].chosen == 1 and doc.dirty
    path = tmp_path / "handoff.json"
    assert window.save_to(path) and takes_path(path).exists() and not doc.dirty
    calls = len(sampler.yielded)

    reopened = make_window(generate=sampler)
    assert reopened.open_file(path)
    assert [t.seed for t in reopened.doc.takes] == [4, 9] and reopened.doc.variation == 1
    assert reopened.doc.clip is not None and not reopened.session.outdated and len(sampler.yielded) == calls
    panel = reopened.properties              # the settings the shown take was made with, to make it again
    assert panel.seed.value() == 9 and panel.variations.value() == 2 and panel.steps.value() == 3
    panel.take.setFocus()
    qtbot.keyClick(panel.take, Qt.Key_Up)                          # back to take 1
    assert reopened.doc.take_index == 0 and panel.take.currentText().startswith("Take 1: seed 4")
    assert panel.seed.value() == 4 and reopened.doc.settings.seed == 4 and not reopened.doc.settings.after_drag


def test_a_damaged_takes_file_opens_the_storyboard_and_says_so(qtbot, window, tmp_path, dialogs):
    path = tmp_path / "handoff.json"
    sample_storyboard().save(path)
    takes_path(path).write_bytes(b"damaged")
    assert window.open_file(path)
    assert window.doc.storyboard.length == 120 and window.doc.takes == []
    assert len(dialogs.errors) == 1 and "without its takes" in dialogs.errors[0]
    assert takes_path(path).read_bytes() == b"damaged"                        # left for the artist
    assert window.save_to(path) and takes_path(path).read_bytes() == b"damaged"   # saving keeps it too


def test_saving_over_a_storyboard_with_takes_drops_its_takes(qtbot, make_window, tmp_path, dialogs):
    window = make_window()
    window.doc.replace_storyboard(sample_storyboard(), None)
    generate(qtbot, window, seed=4)
    path = tmp_path / "scene.json"
    assert window.save_to(path) and takes_path(path).exists()
    window.new_document()
    assert window.doc.takes == [] and window.save_to(path)
    assert not takes_path(path).exists()                                    # not the old scene's motion
    reopened = make_window()
    assert reopened.open_file(path) and reopened.doc.takes == [] and reopened.doc.clip is None


def test_a_setting_changed_during_a_generation_stays_when_its_take_arrives(qtbot, make_window):
    window = make_window(generate=FakeSampler(delay_s=0.05))
    window.doc.replace_storyboard(sample_storyboard(), None)
    window.doc.set_settings(GenerationSettings(steps=3, seed=4))
    with qtbot.waitSignal(window.session.finished, timeout=10_000):
        window.generate()
        window.properties.seed.setValue(9)                     # typed while it runs
    assert window.doc.takes[-1].seed == 4 and window.properties.seed.value() == 9
