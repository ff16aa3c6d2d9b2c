"""View options and tool options are models: the View menu and the properties panel edit them,
the canvas and the 3D view follow, and the view options are there again on the next start."""
from PySide6.QtCore import Qt

from app.document import Document


def test_view_menu_toggles_reach_the_views_and_are_kept(qtbot, make_window):
    window = make_window()
    assert window.canvas.show_onion and window.viewport.options.ghosts
    window.view_actions["onion"].trigger()
    window.view_actions["ghosts"].trigger()
    assert not window.canvas.show_onion and not window.viewport.options.ghosts
    assert not window.view_options.options.onion
    again = make_window()
    assert not again.canvas.show_onion and not again.viewport.options.ghosts
    assert not again.view_actions["onion"].isChecked() and again.view_actions["target_paths"].isChecked()


def test_the_object_shape_is_chosen_in_the_panel_and_drawn_by_the_canvas(qtbot, make_window):
    window = make_window()
    combo = window.properties.shape
    combo.setFocus()
    qtbot.keyClick(combo, Qt.Key_Down)             # rectangle -> lasso, as a person would
    assert window.doc.tool_options.object_shape == "lasso"
    window.doc.set_tool_options(object_shape="rectangle")
    assert combo.currentText() == "rectangle"      # the panel follows the model too


def test_an_unknown_shape_is_refused():
    doc = Document()
    try:
        doc.set_tool_options(object_shape="blob")
    except ValueError as e:
        assert "blob" in str(e)
    else:
        raise AssertionError("an unknown shape was accepted")
