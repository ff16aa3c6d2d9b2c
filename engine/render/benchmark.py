"""How fast the viewport's renderer draws a bundled example while it plays (no Qt).

    python -m engine.render.benchmark [--frames 120] [--size 1280x720] [--orbit] [--png PATH]

Renders consecutive frames of a synthesized two-person scene with a table and its example
storyboard's overlays (keyframe ghosts, sketched and generated paths, contact glows) from one
fixed camera, as the viewport does while playing; with --orbit the camera also turns a degree
every frame, as while a person drags it (nothing cached per camera survives). Prints one JSON
line: median and p95 milliseconds per frame for building the scene (CPU), drawing it (GL passes
until the driver has finished), reading the pixels back and the whole frame; the fps of the
median frame; the GL renderer and the machine.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..storyboard import Storyboard
from ..synth import synthesize
from .renderer import SceneRenderer
from .scene import scene_from_clip
from .sheets import clip_camera

EXAMPLES = Path(__file__).resolve().parents[2] / "resources" / "examples"


@dataclass
class BenchmarkConfig:
    scenario: str = "carry_together"   # synthesized motion; with seed 5 it is carry_table's scene
    seed: int = 5
    storyboard: str = str(EXAMPLES / "carry_table.json")
    width: int = 1280
    height: int = 720
    frames: int = 120                  # timed frames (the clip loops)
    orbit_degrees: float = 0.0         # camera yaw step per frame
    warmup: int = 3                    # untimed first frames: shader compiles, buffer growth
    png: str | None = None             # write the last frame here


def machine() -> dict:
    cpu = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                if line.startswith("model name")), platform.processor() or "unknown")
    return {"cpu": cpu, "cores": os.cpu_count(), "load_average": [round(x, 2) for x in os.getloadavg()],
            "LP_NUM_THREADS": os.environ.get("LP_NUM_THREADS")}


def summary(seconds: list[float]) -> dict:
    ms = np.asarray(seconds) * 1e3
    return {"median": round(float(np.median(ms)), 2), "p95": round(float(np.percentile(ms, 95)), 2)}


def run(config: BenchmarkConfig) -> dict:
    clip = synthesize(config.scenario, config.seed)
    storyboard = Storyboard.load(config.storyboard)
    renderer = SceneRenderer(config.width, config.height)
    camera = clip_camera(clip, storyboard, config.width / config.height)  # framed as the contact sheets are
    times: dict[str, list[float]] = {"scene": [], "draw": [], "readback": [], "frame": []}
    for n in range(config.warmup + config.frames):
        camera.orbit(config.orbit_degrees, 0.0)
        t0 = time.perf_counter()
        scene = scene_from_clip(clip, n % clip.num_frames, storyboard)
        t1 = time.perf_counter()
        renderer.draw(scene, camera)
        renderer.ctx.finish()
        t2 = time.perf_counter()
        image = renderer.read()
        t3 = time.perf_counter()
        if n >= config.warmup:
            for key, seconds in zip(times, (t1 - t0, t2 - t1, t3 - t2, t3 - t0)):
                times[key].append(seconds)
    if config.png:
        from PIL import Image
        Image.fromarray(image[..., :3]).save(config.png)   # alpha is not meaningful
    out = {f"{key}_ms": summary(values) for key, values in times.items()}
    out["fps"] = round(1e3 / out["frame_ms"]["median"], 1)
    out.update(size=[config.width, config.height], frames=config.frames, orbit=bool(config.orbit_degrees),
               gl_renderer=renderer.ctx.info["GL_RENDERER"], machine=machine())
    renderer.release()
    return out


def main(argv: list[str] | None = None) -> None:
    defaults = BenchmarkConfig()
    parser = argparse.ArgumentParser(prog="python -m engine.render.benchmark", description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=defaults.frames)
    parser.add_argument("--size", default=f"{defaults.width}x{defaults.height}", help="WIDTHxHEIGHT")
    parser.add_argument("--orbit", action="store_true", help="turn the camera 1 degree per frame")
    parser.add_argument("--png", default=None, help="save the last frame")
    args = parser.parse_args(argv)
    width, height = (int(v) for v in args.size.lower().split("x"))
    config = BenchmarkConfig(width=width, height=height, frames=args.frames, orbit_degrees=float(args.orbit),
                             png=args.png)
    print(json.dumps(run(config)))


if __name__ == "__main__":
    main()
