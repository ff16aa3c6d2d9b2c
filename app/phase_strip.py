"""The phase strip: the CTMC occupancy of approach / contact / carry over the motion's frames
as stacked areas (pyqtgraph), the storyboard's contact spans as bars below it, and the
playhead. Scrub it like the timeline. `set_phase` is cheap (three setData calls) so it can run
at every streamed sampler step.
"""
from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt

from engine.clip import PHASES

from .document import Document
from .timeline import LABEL_W, MARGIN

PHASE_COLORS = ("#8ecae6", "#ffb703", "#8f5fbf")   # approach, contact, carry
PLAYHEAD = "#d1495b"
LANE = 0.16                                          # height of one contact-span lane (plot units)
EMPTY_HINT = "phases appear while generating"
NO_CONTACTS_HINT = "no contacts or objects: no phases to plan"
MAX_POINTS = 1000   # per curve: the strip is narrower than this in pixels, and a 240 fps x 120 s
                    # clip's 28800 points took 0.75 s to redraw at every streamed step


def phase_legend_html() -> str:
    """Colour swatches naming the phases, for a label beside the strip (rich text)."""
    return "&nbsp;&nbsp;".join(f'<span style="color:{c}">&#9632;</span> {name}' for c, name in zip(PHASE_COLORS, PHASES)) + (
        '&nbsp;&nbsp;<span style="color:#777">&#9644;</span> contacts')


class PhaseStrip(pg.PlotWidget):
    def __init__(self, document: Document, parent=None):
        super().__init__(parent, background="#fbfaf7")
        self._doc = document
        item = self.getPlotItem()
        item.setMenuEnabled(False)
        item.hideButtons()
        item.setMouseEnabled(x=False, y=False)
        item.hideAxis("bottom")
        axis = item.getAxis("left")
        axis.setWidth(LABEL_W)
        axis.setTicks([[(0.5, "phase")], []])
        axis.setPen(pg.mkPen("#b0aa9c"))
        axis.setTextPen(pg.mkPen("#3a3a3a"))
        item.layout.setContentsMargins(0, 2, MARGIN, 2)
        self.setMinimumHeight(70)
        self._curves = [pg.PlotCurveItem(pen=None) for _ in range(len(PHASES) + 1)]
        for curve in self._curves:
            item.addItem(curve)
        for i in range(len(PHASES)):
            item.addItem(pg.FillBetweenItem(self._curves[i], self._curves[i + 1], brush=pg.mkBrush(PHASE_COLORS[i])))
        self._spans = pg.BarGraphItem(x0=[], x1=[], y0=[], height=[], brushes=[])
        item.addItem(self._spans)
        self._playhead = pg.InfiniteLine(angle=90, pen=pg.mkPen(PLAYHEAD, width=1.6))
        item.addItem(self._playhead)
        self.empty_hint = pg.TextItem(EMPTY_HINT, color="#b0aa9c", anchor=(0.5, 0.5))
        item.addItem(self.empty_hint, ignoreBounds=True)
        document.frameChanged.connect(self._playhead.setValue)
        document.storyboardChanged.connect(self._on_storyboard)
        document.resultChanged.connect(self.show_document_phase)
        self._on_storyboard()              # shows the document's phase too

    def set_phase(self, phase: np.ndarray | None) -> None:
        """Show an occupancy (N, 3), rows summing to 1; None shows an empty strip, and so does a
        storyboard with neither contacts nor objects (the planner's "carry" there carries nothing)."""
        sb = self._doc.storyboard
        n = sb.length
        if not (sb.contacts or sb.objects):
            phase = None
        if phase is None:
            stacked = np.zeros((len(PHASES) + 1, n))
        else:
            phase = np.clip(np.asarray(phase, float), 0, None)
            stacked = np.vstack([np.zeros(len(phase)), np.cumsum(phase, axis=1).T])
        frames = stacked.shape[1]
        x = np.unique(np.append(np.arange(0, frames, -(-frames // (MAX_POINTS - 1))), frames - 1)) if frames else np.arange(0)
        for curve, y in zip(self._curves, stacked):
            curve.setData(x.astype(float), y[x])
        self.empty_hint.setVisible(phase is None)

    def show_document_phase(self) -> None:
        """Back to the last finished generation's occupancy (after streaming, cancel or error)."""
        self.set_phase(self._doc.phase)

    def _on_storyboard(self) -> None:
        sb = self._doc.storyboard
        contacts = sb.contacts
        lanes = np.arange(len(contacts))
        self._spans.setOpts(x0=[c.start for c in contacts], x1=[c.end + 1 for c in contacts],
                            y0=-(lanes + 1) * LANE - 0.04, height=LANE * 0.75,
                            brushes=[pg.mkBrush(sb.agents[sb.agent_index(c.agent)].color) for c in contacts],
                            pen=pg.mkPen(None))
        bottom = -(max(len(contacts), 1)) * LANE - 0.06
        self.getPlotItem().setRange(xRange=(0, sb.length - 1), yRange=(bottom, 1.0), padding=0)
        self.empty_hint.setPos((sb.length - 1) / 2, 0.5)
        self.empty_hint.setText(EMPTY_HINT if sb.contacts or sb.objects else NO_CONTACTS_HINT)
        self._playhead.setValue(self._doc.frame)
        self.show_document_phase()

    # ---- scrubbing ---------------------------------------------------------------------------
    def _scrub(self, event) -> None:
        view = self.getPlotItem().getViewBox()
        point = view.mapSceneToView(self.mapToScene(event.position().toPoint()))
        self._doc.set_frame(int(round(point.x())))

    def mousePressEvent(self, event):
        if event.button() == Qt.LeftButton:
            self._scrub(event)

    def mouseMoveEvent(self, event):
        if event.buttons() & Qt.LeftButton:
            self._scrub(event)

    def mouseReleaseEvent(self, event):
        pass

    def wheelEvent(self, event):
        event.ignore()   # the strip's range follows the storyboard; no zooming by accident
