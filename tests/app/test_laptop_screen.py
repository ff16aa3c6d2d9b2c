"""The main window on a 1366 x 768 laptop screen: it fits, every panel keeps the room it needs
without overlapping another, and the layout the artist left is there on the next start."""
from PySide6.QtCore import QRect, QSize, Qt
from PySide6.QtWidgets import QDockWidget

# What a 1366 x 768 screen leaves a window: a desktop panel (32 px) and the title bar (30 px).
LAPTOP_ROOM = QSize(1366, 768 - 32 - 30)


def _in_window(window, widget) -> QRect:
    return QRect(widget.mapTo(window, widget.rect().topLeft()), widget.size())


def test_the_tests_run_on_a_laptop_screen(qapp):
    assert qapp.primaryScreen().availableGeometry().size() == QSize(1366, 768)


def test_the_window_fits_and_no_panel_overlaps_another(qtbot, make_window):
    window = make_window()
    qtbot.waitExposed(window)
    assert window.screen().availableGeometry().contains(window.frameGeometry())
    smallest = window.minimumSizeHint()
    assert smallest.width() <= 1280 and smallest.height() <= 720

    window.showNormal()
    window.resize(LAPTOP_ROOM)
    qtbot.waitUntil(lambda: window.size() == LAPTOP_ROOM)
    for front in (window.viewport_dock, window.floor_plan_dock):      # tabbed: each in turn in front
        front.raise_()
        qtbot.waitUntil(lambda: window.rect().contains(_in_window(window, front)))
        behind = window.tabifiedDockWidgets(front)
        panels = {"canvas": window.canvas, **{d.objectName(): d for d in window.findChildren(QDockWidget) if d not in behind}}
        rects = {name: _in_window(window, w) for name, w in panels.items()}
        names = list(rects)
        for i, a in enumerate(names):
            assert window.rect().contains(rects[a]), a
            for b in names[i + 1:]:
                assert not rects[a].intersects(rects[b]), (a, b)
        for dock in panels.values():
            if dock is not window.canvas:
                inner, needed = dock.widget().size(), dock.widget().minimumSizeHint()
                assert inner.width() >= needed.width() and inner.height() >= needed.height(), dock.objectName()
    assert window.canvas.width() >= 300 and window.canvas.height() >= 300


def test_every_property_is_reachable_by_scrolling(qtbot, make_window):
    window = make_window()
    window.showNormal()
    window.resize(LAPTOP_ROOM)
    qtbot.waitUntil(lambda: window.size() == LAPTOP_ROOM)
    scroll = window.properties_dock.widget()
    last = window.properties.variation            # the lowest field of the panel
    scroll.ensureWidgetVisible(last)
    visible = QRect(last.mapTo(scroll.viewport(), last.rect().topLeft()), last.size())
    assert scroll.viewport().rect().contains(visible)
    assert window.properties.width() >= window.properties.minimumSizeHint().width()   # nothing clipped sideways


def test_the_layout_is_restored_on_the_next_start(qtbot, make_window):
    window = make_window()
    window.showNormal()
    window.resize(1200, 680)
    window.viewport_dock.close()
    window.floor_plan_dock.close()
    window.resizeDocks([window.properties_dock], [460], Qt.Horizontal)
    qtbot.waitUntil(lambda: not window.viewport_dock.isVisible() and window.properties_dock.width() == 460)
    window.close()

    again = make_window()
    qtbot.waitExposed(again)
    assert again.size() == QSize(1200, 680)
    assert not again.viewport_dock.isVisible() and not again.floor_plan_dock.isVisible()
    assert again.properties_dock.width() == 460


def test_generate_stays_on_the_toolbar_of_a_narrow_window(qtbot, make_window):
    """At 1024 and 900 px (the window goes no narrower than 884) the longest labels shorten,
    Generate keeps its place on the bar (not in the overflow menu), and at full width the labels
    come back."""
    window = make_window()
    window.showNormal()
    bar, generate = window.toolbar.bar, window.act_generate
    for width in (1024, 900):
        window.resize(width, 600)
        qtbot.waitUntil(lambda: window.width() == width)
        qtbot.waitUntil(lambda: bar.widgetForAction(generate).isVisible())
        assert window.act_mirror.iconText() == "Mirror"
    window.resize(LAPTOP_ROOM)
    qtbot.waitUntil(lambda: window.act_mirror.iconText() == "Mirror Keypose")
    assert bar.widgetForAction(generate).isVisible() and window.act_undo.iconText() == "Undo"


def test_the_properties_panel_leaves_the_canvas_room_on_a_small_window(make_window):
    """Its widest rows (a key's hold with its easing, the object's three sizes) are laid out so
    that the panel can be narrowed to about a quarter of a 1280 px window."""
    window = make_window()
    window.open_file("resources/examples/carry_table.json")
    assert window.properties.minimumSizeHint().width() <= 320

