"""Regenerates resources/examples/*.json: storyboards traced (sketchify, hand-drawn noise)
from procedurally synthesized scenes, so that every example is consistent and physically
possible. Run from the repository root: python3 scripts/make_examples.py"""
from dataclasses import replace
from pathlib import Path

from engine.sketchify import sketchify
from engine.synth import synthesize

OUT = Path(__file__).resolve().parents[1] / "resources" / "examples"
# name: (scenario, synth seed, text); seeds picked for the object named in the text.
EXAMPLES = {
    "carry_table": ("carry_together", 5, "two people carry a table along a curved path and set it down"),
    "let_go": ("let_go", 0, "they carry a box together, then one lets go and the other finishes"),
    "box_handoff": ("handoff", 2, "one person hands a box to the other"),
    "handshake": ("handshake", 3, "two people meet and shake hands"),
}


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    for name, (scenario, seed, text) in EXAMPLES.items():
        sb = sketchify(synthesize(scenario, seed), keyframes=4, noise=0.25, seed=seed)
        if scenario == "handshake":  # the synthesized scene's idle object is not part of this story
            sb = replace(sb, objects=[], object_keys=[], object_paths=[],
                         contacts=[c for c in sb.contacts if c.object is None])
        sb.text = text
        sb.validate()
        sb.save(OUT / f"{name}.json")
        print(f"{name}: {len(sb.keyposes)} keyposes, {len(sb.trajectories)} paths, {len(sb.contacts)} contacts")


if __name__ == "__main__":
    main()
