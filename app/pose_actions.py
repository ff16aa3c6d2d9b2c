"""The window's keypose actions (a mixin of MainWindow, like files.py): copy the previous keypose,
copy and paste a pose between keys and agents, mirror, stamp a pose of the library, delete. Each acts on the selected agent at the playhead
through one undoable command."""
from __future__ import annotations

from engine.poses import POSE_NAMES

from . import commands as cmd
from .poses import placed_pose, previous_keypose, stamped_pose
from .timeline import delete_keyframe


class PoseActions:
    """Needs self.doc (Document) and self.statusBar() (QMainWindow)."""
    _copied_pose = None          # (points (22, 2), mask (22,), depth (22,) | None) of Copy Pose

    def copy_previous_keypose(self) -> None:
        doc = self.doc
        agent = doc.selection.agent
        previous = previous_keypose(doc.storyboard, agent, doc.frame)
        if previous is None:
            self.statusBar().showMessage(f"Agent {agent} has no keypose before frame {doc.frame}.", 5000)
            return
        doc.undo_stack.push(cmd.SetKeypose(doc, agent, doc.frame, previous.points, previous.mask,
                                           f"Copy keypose from frame {previous.frame}", previous.depth))

    def copy_pose(self) -> None:
        doc = self.doc
        key = cmd.find_keypose(doc.storyboard, doc.selection.agent, doc.frame)
        if key is None:
            self.statusBar().showMessage("No keypose at the playhead to copy.", 5000)
            return
        self._copied_pose = (key.points.copy(), key.mask.copy(), key.depth)
        self.statusBar().showMessage(f"Copied {doc.selection.agent}'s pose at frame {doc.frame}: "
                                     "paste it on any agent and frame (M mirrors it).", 5000)

    def paste_pose(self) -> None:
        """The copied pose on the selected agent at the playhead, standing where that agent stands."""
        doc = self.doc
        if self._copied_pose is None:
            self.statusBar().showMessage("Copy a keypose first (Edit > Copy Pose).", 5000)
            return
        points, mask, depth = self._copied_pose
        points, mask = placed_pose(doc.storyboard, doc.selection.agent, doc.frame, points, mask)
        doc.undo_stack.push(cmd.SetKeypose(doc, doc.selection.agent, doc.frame, points, mask, "Paste pose", depth))

    def mirror_keypose(self) -> None:
        doc = self.doc
        if cmd.find_keypose(doc.storyboard, doc.selection.agent, doc.frame) is None:
            self.statusBar().showMessage("No keypose at the playhead to mirror.", 5000)
            return
        doc.undo_stack.push(cmd.MirrorKeypose(doc, doc.selection.agent, doc.frame))

    def stamp_pose(self, name: str) -> None:
        doc = self.doc
        points, mask, depth = stamped_pose(doc.storyboard, doc.selection.agent, doc.frame, name)
        doc.undo_stack.push(cmd.SetKeypose(doc, doc.selection.agent, doc.frame, points, mask, f"Stamp pose: {name}", depth))

    def delete_keypose(self) -> None:
        doc = self.doc
        if cmd.find_keypose(doc.storyboard, doc.selection.agent, doc.frame) is not None:
            delete_keyframe(doc, "agent", doc.selection.agent, doc.frame)

    def build_pose_library(self, menu) -> None:
        """Fill `menu` (Edit > Stamp Pose) with the library's poses."""
        menu.setToolTipsVisible(True)
        for name in POSE_NAMES:
            action = menu.addAction(name.capitalize())
            action.setToolTip(f"Pose the selected agent at the playhead: {name}, standing where it stands")
            action.triggered.connect(lambda _=False, name=name: self.stamp_pose(name))
