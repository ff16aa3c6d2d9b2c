"""The timeline: a ruler, one track per agent and per object with keyframe markers, the
playhead, and the frame span used by new trajectories and contacts.

Mouse: click or drag to scrub; drag a marker to retime it; shift-drag to select a frame span
(click without shift clears it); double-click an agent's track to add a keypose there (a copy
of the previous keyframe); right-click a marker to delete it.

PlaybackControls is the header's transport (play / pause, loop, speed): a view of the Playback
model, which it changes only through its setters.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from PySide6.QtCore import QPointF, QRectF, Qt
from PySide6.QtGui import QColor, QPainter, QPainterPath, QPen, QPolygonF
from PySide6.QtWidgets import QComboBox, QHBoxLayout, QMenu, QStyle, QToolButton, QWidget

from engine.finishing.timing import holds

from . import commands as cmd
from .document import Document
from .playback import SPEEDS, Playback, speed_label
from .poses import new_keypose

LABEL_W = 72      # the track-name column; the phase strip's axis is made as wide to line up
RULER_H = 20
ROW_H = 22
MARGIN = 12
PLAYHEAD = QColor("#d1495b")
SPAN = QColor(46, 134, 171, 40)


@dataclass(frozen=True)
class Track:
    kind: str     # "agent" or "object"
    owner: str
    color: str


RULER_STEPS = (5,) + tuple(m * 10 ** e for e in range(1, 7) for m in (1, 2, 5))   # frames between ruler ticks


def ruler_steps(length: int, width: float) -> tuple[int, int]:
    """Frames between the ruler's ticks and between its labels for a clip drawn `width` px wide:
    ticks at least 5 px apart, labels at least 40 px (a 240 fps x 2 min clip's labels every 20
    frames overprinted into a grey band)."""
    per_frame = width / max(length, 1)
    tick = next((s for s in RULER_STEPS if s * per_frame >= 5), RULER_STEPS[-1])
    every = next((s for s in RULER_STEPS if s >= 10 and s * per_frame >= 40 and s % tick == 0), RULER_STEPS[-1])
    return tick, every


def frame_to_x(frame: float, length: int, width: int) -> float:
    return LABEL_W + frame * (width - LABEL_W - MARGIN) / max(length - 1, 1)


def x_to_frame(x: float, length: int, width: int) -> int:
    f = (x - LABEL_W) * max(length - 1, 1) / max(width - LABEL_W - MARGIN, 1)
    return int(np.clip(round(f), 0, length - 1))


class Timeline(QWidget):
    def __init__(self, document: Document, parent: QWidget | None = None):
        super().__init__(parent)
        self._doc = document
        self._drag: tuple[str, object] | None = None   # ("scrub", None) | ("span", start) | ("marker", (track, old, new))
        for signal in (document.storyboardChanged, document.frameChanged, document.spanChanged,
                       document.selectionChanged):
            signal.connect(self._refresh)
        self._refresh()

    def tracks(self) -> list[Track]:
        sb = self._doc.storyboard
        return ([Track("agent", a.id, a.color) for a in sb.agents]
                + [Track("object", o.id, "#8a6d3b") for o in sb.objects])

    def key_frames(self, track: Track) -> list[int]:
        sb = self._doc.storyboard
        keys = sb.keyposes if track.kind == "agent" else sb.object_keys
        attr = "agent" if track.kind == "agent" else "object"
        return sorted({k.frame for k in keys if getattr(k, attr) == track.owner})

    def _refresh(self, *_):
        self.setMinimumHeight(RULER_H + ROW_H * len(self.tracks()) + 4)
        self.update()

    # ---- geometry ------------------------------------------------------------------------------
    def _x(self, frame: float) -> float:
        return frame_to_x(frame, self._doc.storyboard.length, self.width())

    def _frame(self, x: float) -> int:
        return x_to_frame(x, self._doc.storyboard.length, self.width())

    def _row(self, y: float) -> int | None:
        row = int((y - RULER_H) // ROW_H)
        return row if y >= RULER_H and row < len(self.tracks()) else None

    def marker_at(self, x: float, y: float) -> tuple[Track, int] | None:
        row = self._row(y)
        if row is None:
            return None
        track = self.tracks()[row]
        for f in self.key_frames(track):
            if abs(self._x(f) - x) <= 6:
                return track, f
        return None

    # ---- mouse -----------------------------------------------------------------------------------
    def mousePressEvent(self, event):
        x, y = event.position().x(), event.position().y()
        frame = self._frame(x)
        marker = self.marker_at(x, y)
        if event.button() == Qt.RightButton:
            if marker:
                self._offer_delete(marker, event.globalPosition().toPoint())
            return
        if event.button() != Qt.LeftButton:
            return
        row = self._row(y)
        if row is not None and self.tracks()[row].kind == "agent":
            self._doc.select(agent=self.tracks()[row].owner)
        if event.modifiers() & Qt.ShiftModifier:
            self._drag = ("span", frame)
        elif marker:
            self._drag = ("marker", (marker[0], marker[1], marker[1]))
            self._doc.set_frame(marker[1])
        else:
            self._drag = ("scrub", None)
            self._doc.set_span(None)
            self._doc.set_frame(frame)

    def mouseMoveEvent(self, event):
        if self._drag is None:
            return
        frame = self._frame(event.position().x())
        kind, data = self._drag
        if kind == "scrub":
            self._doc.set_frame(frame)
        elif kind == "span":
            self._doc.set_span((data, frame))
        else:
            frame = self._between_neighbours(data[0], data[1], frame)
            self._drag = ("marker", (data[0], data[1], frame))
            self._doc.set_frame(frame)
            self.update()

    def _between_neighbours(self, track: Track, old: int, frame: int) -> int:
        """frame, kept between the keys either side of the dragged one on its track and past the
        hold of the one before: a key does not pass over or replace another (dragged past the
        timeline's end, the last one went), nor land inside a held pose."""
        frames = self.key_frames(track)
        held = {k.frame: k.hold for k in self._doc.storyboard.keyposes if k.agent == track.owner} \
            if track.kind == "agent" else {}
        before = max((f + held.get(f, 0) for f in frames if f < old), default=-1)
        after = min((f for f in frames if f > old), default=self._doc.storyboard.length)
        return int(np.clip(frame, before + 1, after - 1))

    def mouseReleaseEvent(self, event):
        drag, self._drag = self._drag, None
        if drag and drag[0] == "marker":
            track, old, _ = drag[1]
            new = self._between_neighbours(track, old, self._frame(event.position().x()))
            if new != old:
                self._doc.undo_stack.push(cmd.RetimeKeyframe(self._doc, track.kind, track.owner, old, new))

    def mouseDoubleClickEvent(self, event):
        row = self._row(event.position().y())
        if row is None or self.tracks()[row].kind != "agent":
            return
        agent, frame = self.tracks()[row].owner, self._frame(event.position().x())
        if cmd.find_keypose(self._doc.storyboard, agent, frame) is None:
            points, mask = new_keypose(self._doc.storyboard, agent, frame)
            self._doc.undo_stack.push(cmd.SetKeypose(self._doc, agent, frame, points, mask))
        self._doc.set_frame(frame)

    def _offer_delete(self, marker: tuple[Track, int], where) -> None:
        track, frame = marker
        menu = QMenu(self)
        action = menu.addAction(f"Delete keyframe {frame}")
        if menu.exec(where) is action:
            delete_keyframe(self._doc, track.kind, track.owner, frame)

    # ---- painting ------------------------------------------------------------------------------
    def paintEvent(self, event):
        p = QPainter(self)
        p.setRenderHint(QPainter.Antialiasing)
        p.fillRect(self.rect(), QColor("#fbfaf7"))
        sb = self._doc.storyboard
        w = self.width()
        tick, every = ruler_steps(sb.length, w)
        p.setPen(QColor("#8a857a"))
        for f in range(0, sb.length, tick):
            x = self._x(f)
            labelled = f % every == 0
            p.drawLine(QPointF(x, RULER_H - (8 if labelled else 4)), QPointF(x, RULER_H))
            if labelled:
                p.drawText(QPointF(x + 2, RULER_H - 8), str(f))
        # Frame span.
        if self._doc.span:
            lo, hi = self._doc.span
            p.fillRect(QRectF(QPointF(self._x(lo), 0), QPointF(self._x(hi), self.height())), SPAN)
        # Tracks.
        moving = self._drag[1] if self._drag and self._drag[0] == "marker" else None
        for row, track in enumerate(self.tracks()):
            top = RULER_H + row * ROW_H
            selected = track.kind == "agent" and track.owner == self._doc.selection.agent
            p.fillRect(QRectF(0, top, w, ROW_H - 1), QColor("#f1eee7" if selected else "#f7f5f0"))
            p.fillRect(QRectF(0, top + 3, 4, ROW_H - 7), QColor(track.color))
            p.setPen(QColor("#3a3a3a"))
            p.drawText(QRectF(10, top, LABEL_W - 12, ROW_H), Qt.AlignVCenter, track.owner)
            timing = self._key_timing(track)
            for f in self.key_frames(track):
                held, ease_in, ease_out = timing.get(f, (0, False, False))
                if moving and moving[0] == track and moving[1] == f:
                    f = moving[2]
                y, color = top + ROW_H / 2, QColor(track.color)
                if held:                     # a hold: a bar as long as the pose stays
                    hold_color = QColor(color)
                    hold_color.setAlpha(110)
                    p.fillRect(QRectF(QPointF(self._x(f), y - 2.5), QPointF(self._x(f + held), y + 2.5)), hold_color)
                self._key_marker(p, self._x(f), y, color, ease_in, ease_out)
        # Playhead.
        x = self._x(self._doc.frame)
        p.setPen(QPen(PLAYHEAD, 1.6))
        p.drawLine(QPointF(x, 0), QPointF(x, self.height()))
        p.setBrush(PLAYHEAD)
        p.drawPolygon(QPolygonF([QPointF(x - 5, 0), QPointF(x + 5, 0), QPointF(x, 7)]))
        p.end()

    def _key_timing(self, track: Track) -> dict[int, tuple[int, bool, bool]]:
        """{frame: (frames held, ease in, ease out)} of an agent track's keyposes."""
        if track.kind != "agent":
            return {}
        return {k.frame: (end - k.frame, k.ease_in, k.ease_out) for k, end in holds(self._doc.storyboard, track.owner)}

    @staticmethod
    def _key_marker(p: QPainter, x: float, y: float, color: QColor, ease_in: bool = False, ease_out: bool = False):
        """A key as a diamond; an eased side is round, as animation editors draw a smooth key."""
        r = 5.5
        p.setPen(QPen(color.darker(150), 1))
        p.setBrush(color)
        path = QPainterPath(QPointF(x, y - r))
        for eased, side in ((ease_out, 1), (ease_in, -1)):   # right half, then left half, clockwise
            if eased:
                path.arcTo(QRectF(x - r, y - r, 2 * r, 2 * r), 90 if side == 1 else 270, -180)
            else:
                path.lineTo(QPointF(x + side * r, y))
                path.lineTo(QPointF(x, y + side * r))
        p.drawPath(path)


class PlaybackControls(QWidget):
    """Play / pause, a loop toggle and a speed selector bound to `playback`."""

    def __init__(self, playback: Playback, parent: QWidget | None = None):
        super().__init__(parent)
        self._playback = playback
        self.play_button = QToolButton()
        self.play_button.setToolTip("Play / Pause (Space); Left / Right step one frame")
        self.play_button.clicked.connect(playback.toggle)
        self.loop_button = QToolButton()
        self.loop_button.setText("\u27f2 Loop")
        self.loop_button.setToolTip("Loop playback; off, it stops at the last frame")
        self.loop_button.setCheckable(True)
        self.speed_box = QComboBox()
        self.speed_box.setToolTip("Playback speed")
        for speed in SPEEDS:
            self.speed_box.addItem(speed_label(speed), speed)
        layout = QHBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.setSpacing(4)
        for widget in (self.play_button, self.loop_button, self.speed_box):
            layout.addWidget(widget)
        self._show_playing(playback.playing)
        self.loop_button.setChecked(playback.loop)
        self._show_speed(playback.speed)
        # Connected after the initial state is shown, so showing it does not write it back.
        self.loop_button.toggled.connect(playback.set_loop)
        self.speed_box.currentIndexChanged.connect(self._choose_speed)
        playback.playingChanged.connect(self._show_playing)
        playback.loopChanged.connect(self.loop_button.setChecked)
        playback.speedChanged.connect(self._show_speed)

    def _show_playing(self, playing: bool) -> None:
        # The style's own icons: a font may lack the pause sign (DejaVu does: an empty box).
        self.play_button.setText("Pause" if playing else "Play")
        self.play_button.setIcon(self.style().standardIcon(QStyle.SP_MediaPause if playing else QStyle.SP_MediaPlay))

    def _choose_speed(self, index: int) -> None:
        if index >= 0:   # -1: a rate set elsewhere that the list does not offer
            self._playback.set_speed(self.speed_box.itemData(index))

    def _show_speed(self, speed: float) -> None:
        self.speed_box.setCurrentIndex(self.speed_box.findData(speed))


def delete_keyframe(document: Document, kind: str, owner: str, frame: int) -> None:
    """Delete an agent's keypose or an object's key at `frame` (undoable)."""
    if kind == "agent":
        document.undo_stack.push(cmd.DeleteKeypose(document, owner, frame))
        return
    for i, k in enumerate(document.storyboard.object_keys):
        if k.object == owner and k.frame == frame:
            document.undo_stack.push(cmd.DeleteObjectKey(document, i))
            return
