"""`sketch2colab demo`: the bundled example storyboards end to end, headless.

For each resources/examples/*.json: generate with the default sampler, save the motion, a
contact sheet PNG and a GIF (engine.render.sheets), and report the adherence figures.
"""
from __future__ import annotations

import sys
from pathlib import Path

from .generate import generate, summary
from .sampling.config import SamplerConfig
from .storyboard import Storyboard

EXAMPLES = Path(__file__).resolve().parents[1] / "resources" / "examples"


def run_demo(out_dir: str | Path, config: SamplerConfig = SamplerConfig(), examples: Path = EXAMPLES,
             render: bool = True) -> list[dict]:
    from .models.bundle import load_default
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    bundle = load_default()
    if not bundle.trained:
        print("note: no trained checkpoint is installed; the untrained model's output is not motion yet",
              file=sys.stderr)
    rows = []
    for path in sorted(examples.glob("*.json")):
        sb = Storyboard.load(path)
        print(f"{path.stem}: {sb.text}", file=sys.stderr)
        result = generate(sb, config, bundle)
        clip = result.clips[0]
        clip.save(out_dir / f"{path.stem}.npz")
        if render:
            from .render.sheets import write_contact_sheet, write_gif
            write_contact_sheet(clip, out_dir / f"{path.stem}_sheet.png", storyboard=sb)
            write_gif(clip, out_dir / f"{path.stem}.gif", storyboard=sb)
        rows.append({"example": path.stem, **summary(result, sb, config.method)})
    return rows
