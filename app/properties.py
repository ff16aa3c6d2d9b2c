"""The properties panel: the clip's length, frame rate and text (what happens, in words), selection (agent, joint), the selected
object's type and size, the contact list, and the generation settings with a picker among the
generated variations.
It reads the document on every change and writes back through setters and commands."""
from __future__ import annotations

from dataclasses import replace

from PySide6.QtCore import QEvent, Qt
from PySide6.QtWidgets import (QCheckBox, QComboBox, QDoubleSpinBox, QFormLayout, QGroupBox, QHBoxLayout, QLabel,
                               QLineEdit, QListWidget, QMessageBox, QPushButton, QSpinBox, QVBoxLayout, QWidget)

from engine.objects import DEFAULT_SIZES, OBJECT_TYPES
from engine.skeleton import JOINT_NAMES
from engine.storyboard import MAX_SECONDS, SPANS, Storyboard
from engine.takes import Take

from . import commands as cmd
from .document import OBJECT_PATH, OBJECT_SHAPES, Document

# The joints artists draw paths for most, first; then the rest of the skeleton.
PATH_JOINTS = ("pelvis", "head", "l_wrist", "r_wrist", "l_foot", "r_foot")
JOINT_CHOICES = PATH_JOINTS + tuple(j for j in JOINT_NAMES if j not in PATH_JOINTS) + (OBJECT_PATH,)


class PropertiesPanel(QWidget):

    def __init__(self, document: Document, parent: QWidget | None = None):
        super().__init__(parent)
        self._doc = document
        layout = QVBoxLayout(self)
        layout.setContentsMargins(6, 6, 6, 6)

        box = QGroupBox("Clip")
        form = QFormLayout(box)
        self.frames = QSpinBox()
        self.frames.setSuffix(" frames")
        self.fps = self._spin(1.0, 240.0, 1.0, 2, " fps")
        self.fps.setToolTip("A new frame rate keeps every key, path and contact at its time")
        self.duration = QLabel()
        timing = QHBoxLayout()
        timing.addWidget(self.frames)
        timing.addWidget(self.fps)
        form.addRow("Length", timing)
        form.addRow("", self.duration)
        self.text = QLineEdit()
        self.text.setPlaceholderText("What happens, in words (optional)")
        self.text.setToolTip("e.g. \u201ctwo people carry the box slowly, then the first one lets go\u201d: "
                             "the model reads it with the sketch (Enter to apply)")
        self.text.setClearButtonEnabled(True)
        form.addRow("Text", self.text)
        layout.addWidget(box)

        box = QGroupBox("Selection")
        form = QFormLayout(box)
        self.agent = QComboBox()
        self.joint = QComboBox()
        self.joint.addItems(JOINT_CHOICES)
        self.joint.insertSeparator(len(PATH_JOINTS))
        self.joint.insertSeparator(len(JOINT_CHOICES))
        self.hold = QSpinBox()
        self.hold.setSuffix(" frames held")
        self.hold.setToolTip("How long the selected agent's keypose at the playhead is held still")
        self.ease_in = QCheckBox("Ease in")
        self.ease_in.setToolTip("The motion slows into this keypose")
        self.ease_out = QCheckBox("Ease out")
        self.ease_out.setToolTip("The motion starts slowly out of this keypose (after its hold)")
        easing = QHBoxLayout()      # a row of its own: the panel stays narrow on a laptop screen
        easing.addWidget(self.ease_in)
        easing.addWidget(self.ease_out)
        easing.addStretch(1)
        form.addRow("Agent", self.agent)
        form.addRow("Joint", self.joint)
        form.addRow("Key", self.hold)
        form.addRow("", easing)
        layout.addWidget(box)

        box = QGroupBox("Object")
        form = QFormLayout(box)
        self.object = QComboBox()
        self.object_type = QComboBox()
        self.object_type.addItems(OBJECT_TYPES)
        self.size = [self._spin(0.05, 5.0, 0.05, 2, " m") for _ in range(3)]
        self.shape = QComboBox()
        self.shape.addItems(OBJECT_SHAPES)
        form.addRow("Object", self.object)
        form.addRow("Type", self.object_type)
        for spin, name in zip(self.size, ("Width", "Height", "Depth")):   # a row each: the panel stays narrow
            form.addRow(name, spin)
        form.addRow("Draw as", self.shape)
        layout.addWidget(box)

        box = QGroupBox("Contacts")
        inner = QVBoxLayout(box)
        self.contacts = QListWidget()
        self.contacts.setMaximumHeight(90)
        self.contacts.installEventFilter(self)   # Delete there deletes the contact, not the keypose
        self.delete_contact = QPushButton("Delete contact")
        inner.addWidget(self.contacts)
        inner.addWidget(self.delete_contact)
        layout.addWidget(box)

        box = QGroupBox("Generation")
        form = QFormLayout(box)
        self.seed = QSpinBox()
        self.seed.setRange(0, 2**31 - 1)
        self.steps = QSpinBox()
        self.steps.setRange(1, 200)
        self.cfg = self._spin(0.0, 5.0, 0.1, 2)
        self.text_cfg = self._spin(0.0, 10.0, 0.5, 1)
        self.text_cfg.setToolTip("How strongly the motion follows the storyboard's text where the sketch leaves "
                                 "room (thumbnails); as Guidance: no extra weight. Above it, a third more time.")
        self.use_energy = QCheckBox("Energies")
        self.use_ctmc = QCheckBox("CTMC phases")
        self.steady = QCheckBox("Steady")
        self.steady.setToolTip("Damped guidance: a small stroke edit changes the motion a little instead of "
                               "giving a new take. Feet skate somewhat more.")
        self.variations = QSpinBox()
        self.variations.setRange(1, 8)
        self.variation = QComboBox()
        self.take = QComboBox()
        self.take.setToolTip("Every generation is a take, saved with the storyboard; pick one to see it again")
        form.addRow("Seed", self.seed)
        form.addRow("Steps", self.steps)
        form.addRow("Guidance", self.cfg)
        form.addRow("Text weight", self.text_cfg)
        toggles = QHBoxLayout()
        toggles.addWidget(self.use_energy)
        toggles.addWidget(self.use_ctmc)
        toggles.addWidget(self.steady)
        form.addRow(toggles)
        form.addRow("Variations", self.variations)
        form.addRow("Take", self.take)
        form.addRow("Show", self.variation)
        layout.addWidget(box)
        layout.addStretch(1)

        self.frames.editingFinished.connect(self._apply_length)
        self.fps.editingFinished.connect(self._apply_fps)
        self.text.editingFinished.connect(self._apply_text)
        self.agent.activated.connect(lambda i: document.select(agent=self.agent.itemData(i)))
        self.joint.activated.connect(lambda i: document.select(joint=self.joint.itemText(i)))
        self.object.activated.connect(lambda i: document.select(object=self.object.itemData(i)))
        self.hold.editingFinished.connect(self._apply_key_timing)
        for box in (self.ease_in, self.ease_out):
            box.toggled.connect(self._apply_key_timing)
        document.frameChanged.connect(self._refresh_key_timing)
        self.object_type.activated.connect(self._apply_object)
        for spin in self.size:
            spin.editingFinished.connect(self._apply_object)
        self.shape.currentTextChanged.connect(lambda shape: document.set_tool_options(object_shape=shape))
        document.toolOptionsChanged.connect(lambda: self.shape.setCurrentText(document.tool_options.object_shape))
        self.delete_contact.clicked.connect(self._delete_contact)
        self.contacts.currentRowChanged.connect(lambda row: self.delete_contact.setEnabled(row >= 0))
        for widget in (self.seed, self.steps, self.cfg, self.text_cfg, self.variations):
            widget.valueChanged.connect(self._apply_settings)
        for box in (self.use_energy, self.use_ctmc, self.steady):
            box.toggled.connect(self._apply_settings)
        self.variation.activated.connect(document.choose_variation)
        self.take.activated.connect(document.choose_take)

        document.storyboardChanged.connect(self.refresh)
        document.selectionChanged.connect(self.refresh)
        document.settingsChanged.connect(self.refresh)
        document.resultChanged.connect(self.refresh)
        self.refresh()

    @staticmethod
    def _spin(lo: float, hi: float, step: float, decimals: int, suffix: str = "") -> QDoubleSpinBox:
        spin = QDoubleSpinBox()
        spin.setRange(lo, hi)
        spin.setSingleStep(step)
        spin.setDecimals(decimals)
        spin.setSuffix(suffix)
        return spin

    # ---- document -> widgets -------------------------------------------------------------------
    def refresh(self) -> None:
        doc, sb, sel = self._doc, self._doc.storyboard, self._doc.selection
        widgets = [self.frames, self.fps, self.agent, self.joint, self.object, self.object_type, *self.size,
                   self.contacts, self.seed, self.steps, self.cfg, self.text_cfg, self.use_energy, self.use_ctmc,
                   self.steady, self.variations, self.variation, self.take]
        for w in widgets:
            w.blockSignals(True)
        self.fps.setValue(sb.fps)
        self.frames.setRange(2, int(MAX_SECONDS * sb.fps))
        self.frames.setValue(sb.length)
        self.duration.setText(f"{sb.length / sb.fps:.2f} s")
        if not self.text.isModified():      # never overwrite what is being typed (until Enter)
            self.text.setText(sb.text)
            self.text.setCursorPosition(0)  # a long text shows its beginning
        self.agent.clear()
        for a in sb.agents:
            self.agent.addItem(a.name or a.id, a.id)
        self.agent.setCurrentIndex(self.agent.findData(sel.agent))
        self.joint.setCurrentIndex(self.joint.findText(sel.joint))
        self._refresh_key_timing()
        self.object.clear()
        for o in sb.objects:
            self.object.addItem(o.id, o.id)
        self.object.setCurrentIndex(self.object.findData(sel.object))
        obj = next((o for o in sb.objects if o.id == sel.object), None)
        for w in (self.object_type, *self.size):
            w.setEnabled(obj is not None)
        if obj is not None:
            self.object_type.setCurrentText(obj.spec.type)
            for spin, value in zip(self.size, obj.spec.size):
                spin.setValue(value)
        row = self.contacts.currentRow()
        self.contacts.clear()
        self.contacts.addItems([cmd.describe_contact(c) for c in sb.contacts])
        self.contacts.setCurrentRow(min(row, self.contacts.count() - 1))
        self.delete_contact.setEnabled(self.contacts.currentRow() >= 0)
        s = doc.settings
        for spin, value in ((self.seed, s.seed), (self.steps, s.steps), (self.cfg, s.cfg), (self.text_cfg, s.text_cfg)):
            if spin.value() != value:     # the same value set again retypes the field under the cursor:
                spin.setValue(value)      # typing "2.5" became 2.0, and "0.75" turned guidance off
        self.use_energy.setChecked(s.use_energy)
        self.use_ctmc.setChecked(s.use_ctmc)
        self.steady.setChecked(s.steady)
        self.variations.setValue(s.variations)
        self.variation.clear()
        self.variation.addItems([f"Variation {i + 1} of {len(doc.clips)}" for i in range(len(doc.clips))])
        self.variation.setCurrentIndex(doc.variation if doc.clips else -1)
        self.variation.setEnabled(len(doc.clips) > 1)
        self.take.clear()
        self.take.addItems([_take_label(i, t) for i, t in enumerate(doc.takes)])
        self.take.setCurrentIndex(doc.take_index)
        self.take.setEnabled(len(doc.takes) > 1)
        for w in widgets:
            w.blockSignals(False)

    def _refresh_key_timing(self, *_) -> None:
        """The Key row shows the selected agent's keypose at the playhead (disabled without one)."""
        doc = self._doc
        key = cmd.find_keypose(doc.storyboard, doc.selection.agent, doc.frame)
        later = [k.frame for k in doc.storyboard.keyposes if k.agent == doc.selection.agent and k.frame > doc.frame]
        for w in (self.hold, self.ease_in, self.ease_out):
            w.blockSignals(True)
            w.setEnabled(key is not None)
        # a hold ends before the agent's next key (and the clip's end)
        self.hold.setRange(0, max(0, min([doc.storyboard.length - 1, *(f - 1 for f in later)]) - doc.frame))
        self.hold.setValue(key.hold if key else 0)
        self.ease_in.setChecked(bool(key and key.ease_in))
        self.ease_out.setChecked(bool(key and key.ease_out))
        for w in (self.hold, self.ease_in, self.ease_out):
            w.blockSignals(False)

    # ---- widgets -> document -------------------------------------------------------------------
    def _apply_key_timing(self, *_):
        doc = self._doc
        key = cmd.find_keypose(doc.storyboard, doc.selection.agent, doc.frame)
        timing = (self.hold.value(), self.ease_in.isChecked(), self.ease_out.isChecked())
        if key is not None and timing != (key.hold, key.ease_in, key.ease_out):
            doc.undo_stack.push(cmd.SetKeyTiming(doc, key.agent, key.frame, *timing))

    def _apply_length(self):
        sb, length = self._doc.storyboard, self.frames.value()
        if length == sb.length:
            return
        lost = work_cut_off(sb, length)
        if lost and QMessageBox.question(
                self, "Shorten the clip", f"Shortening the clip to {length} frames {lost}. Shorten it? "
                "(Edit > Undo brings it all back.)", QMessageBox.Yes | QMessageBox.No, QMessageBox.No) != QMessageBox.Yes:
            self.frames.setValue(sb.length)
            return
        self._doc.undo_stack.push(cmd.SetTiming(self._doc, sb.fps, length))

    def commit_text(self) -> None:
        """The Text field's words into the storyboard (as Enter or leaving the field would): a
        generation started while the field has the focus reads them."""
        self._apply_text()

    def _apply_text(self):
        text = " ".join(self.text.text().split())
        self.text.setModified(False)
        if text != self._doc.storyboard.text:
            self._doc.undo_stack.push(cmd.SetText(self._doc, text))

    def _apply_fps(self):
        fps = round(self.fps.value(), 2)
        if fps != self._doc.storyboard.fps:
            self._doc.undo_stack.push(cmd.SetTiming(self._doc, fps))

    def _apply_object(self, *_):
        sel = self._doc.selection.object
        if sel is None:
            return
        spec = self._doc.storyboard.objects[self._doc.storyboard.object_index(sel)].spec
        kind = self.object_type.currentText()
        size = tuple(round(s.value(), 4) for s in self.size)
        if kind != spec.type:
            size = DEFAULT_SIZES[kind]   # a new type starts at its usual size
        if kind != spec.type or size != tuple(round(v, 4) for v in spec.size):
            self._doc.undo_stack.push(cmd.SetObjectSpec(self._doc, sel, kind, size))

    def _apply_settings(self, *_):
        self._doc.set_settings(replace(self._doc.settings, seed=self.seed.value(), steps=self.steps.value(),
                                       cfg=round(self.cfg.value(), 3), text_cfg=round(self.text_cfg.value(), 3),
                                       use_energy=self.use_energy.isChecked(),
                                       use_ctmc=self.use_ctmc.isChecked(), steady=self.steady.isChecked(),
                                       variations=self.variations.value()))

    def eventFilter(self, watched, event) -> bool:
        """Delete or Backspace in the Contacts list deletes its contact: the window's Delete
        shortcut (Delete Keypose) took the key and deleted the figure at the playhead."""
        if watched is self.contacts and event.type() in (QEvent.ShortcutOverride, QEvent.KeyPress) \
                and event.key() in (Qt.Key_Delete, Qt.Key_Backspace) and self.contacts.currentRow() >= 0:
            event.accept()
            if event.type() == QEvent.KeyPress:
                self._delete_contact()
            return True
        return super().eventFilter(watched, event)

    def _delete_contact(self):
        row = self.contacts.currentRow()
        if row >= 0:
            self._doc.undo_stack.push(cmd.DeleteContact(self._doc, row))


def work_cut_off(sb: Storyboard, length: int) -> str:
    """What shortening `sb` to `length` frames would delete or cut, in words ('' when nothing):
    'deletes 2 keyposes and 1 contact and cuts 1 path short'."""
    cut = sb.cut_to(length)
    names = {"keyposes": "keypose", "object_keys": "object key", "trajectories": "path", "object_paths": "object path",
             "contacts": "contact"}
    deleted = [f"{n} {names[field]}{'s' * (n > 1)}" for field in names
               for n in [len(getattr(sb, field)) - len(getattr(cut, field))] if n]
    shortened = sum(1 for field in SPANS for before, after in zip(
        [x for x in getattr(sb, field) if x.start < length], getattr(cut, field)) if after.end < before.end)
    words = [f"deletes {_listed(deleted)}"] if deleted else []
    words += [f"cuts {shortened} span{'s' * (shortened > 1)} short"] if shortened else []
    return ", and ".join(words)


def _listed(items: list[str]) -> str:
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]


def _take_label(index: int, take: Take) -> str:
    """'Take 3: seed 5, 30 steps, 14:02:17' (', after a drag' for a live-previewed edit's)."""
    steps = take.settings.get("steps")
    return (f"Take {index + 1}: seed {take.seed}" + (f", {steps} steps" if steps else "") + f", {take.created[-8:]}"
            + (", after a drag" if take.settings.get("after_drag") else ""))
