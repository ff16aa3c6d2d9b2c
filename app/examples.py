"""The example storyboards shipped in resources/examples, for File > Open Example.

Each example's menu label is its storyboard `text` (the sentence that describes the scene).
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

EXAMPLES_DIR = Path(__file__).resolve().parents[1] / "resources" / "examples"


@dataclass(frozen=True)
class Example:
    path: Path
    label: str


def list_examples(directory: Path = EXAMPLES_DIR) -> list[Example]:
    """The examples in `directory`, by file name; the label falls back to the file's stem when
    the storyboard has no text or cannot be read (opening it then says what is wrong)."""
    examples = []
    for path in sorted(directory.glob("*.json")):
        try:
            text = str(json.loads(path.read_text(encoding="utf-8")).get("text") or "").strip()
        except (OSError, ValueError, AttributeError):
            text = ""
        label = text[:1].upper() + text[1:] if text else path.stem.replace("_", " ")
        examples.append(Example(path, label))
    return examples
