"""Which storyboards the benchmark runs: held-out clips, sketched at fixed seeds.

Protocols (each a list of BenchItems: a storyboard and the held-out clip it was sketched from;
the sketch seed of a scene is its synthesis seed, of a real window its start frame, so cameras
and drawn paths differ between scenes and stay fixed between runs):
  sketch-only   held-out synthesized scenes sketched at noise 0, grouped by scenario.
  noise         the first few of those scenes sketched at each noise level (same sketch seed, so
                camera, keyframes and strokes chosen stay the same and only the roughness grows).
  real          120-frame windows of the held-out CMU salsa take (two people, no object).
  artist        the first few scenes drawn the way artists draw (engine.artist_sketch): by hand,
                and posed with the canvas's tools; scored against the clean held-out clip.
  sketch+text   the sketch-only scenes, clean and at noise 0.6, with a caption of the held-out
                clip as the storyboard's text (engine.synth.captions, seeded by the scene).

Held-out synthesized scenes: the test split of data/synth (engine.dataset.split_files: file
number mod 1000 below 50) when that folder exists. Without it (a fresh clone), the same scenes
are synthesized again: `synth --seed 0` writes clip i with scenario SCENARIOS[i % 5] and seed i,
so the test split IS seeds 0-49 (and 1000-1049), and those seeds are reserved for testing.
Held-out real pairs: data/salsa/60_10_61_10.npz, else imported from
../shared/data/cmu_salsa/60_10.bvh + 61_10.bvh, else the protocol is skipped with a note.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..clip import MotionClip
from ..dataset import HELD_OUT_SALSA_TAKES, split_files
from ..sketchify import sketchify
from ..storyboard import Storyboard
from ..synth import SCENARIOS, synthesize
from ..synth.captions import caption
from ..artist_sketch import ArtistConfig, hand_drawn, posed_with_tools

REPO_ROOT = Path(__file__).resolve().parents[2]
RESERVED_TEST_SEEDS = range(0, 50)      # the seeds the split rule assigns to test (see docstring)
NOISE_LEVELS = (0.2, 0.4, 0.6, 0.8)
ARTIST_KINDS = {"drawn": hand_drawn, "posed": posed_with_tools}


@dataclass
class ProtocolConfig:
    scenarios: tuple[str, ...] = SCENARIOS
    per_scenario: int = 10             # sketch-only storyboards per scenario
    noise_scenes: int = 10             # scenes re-sketched at each noise level
    noise_levels: tuple[float, ...] = NOISE_LEVELS
    artist_scenes: int = 10            # scenes drawn both ways by engine.artist_sketch
    drawing: int = 0                   # added to each scene's seed for its artist-style drawing
    artist: ArtistConfig = field(default_factory=ArtistConfig)   # how roughly it is drawn
    text_noise: tuple[float, ...] = (0.0, 0.6)   # noise levels of the sketch+text storyboards
    real_windows: int = 3              # windows of the held-out salsa take
    window: int = 120                  # frames per real window (6 s at 20 fps)
    real_stride: int = 30
    real_trim: int = 20                # the take trembles in its first second (engine.dataset)
    keyframes: int = 4
    fps: float = 20.0
    data_dir: Path = REPO_ROOT / "data"
    shared_dir: Path = REPO_ROOT.parent / "shared" / "data"


@dataclass
class BenchItem:
    id: str                            # unique within a protocol, e.g. "handoff/000002"
    group: str                         # scenario, or "salsa"
    noise: float
    storyboard: Storyboard
    reference: MotionClip              # the held-out clip the storyboard was sketched from


@dataclass
class Protocol:
    name: str                          # "sketch-only", "noise", "real"
    title: str
    items: list[BenchItem]
    notes: list[str] = field(default_factory=list)


def held_out_scenes(config: ProtocolConfig) -> tuple[list[tuple[str, MotionClip, int]], str]:
    """`per_scenario` held-out scenes of each scenario as (id, clip, seed), and where they came from."""
    wanted = max(config.per_scenario, *(-(-count // len(config.scenarios))
                                        for count in (config.noise_scenes, config.artist_scenes)))
    synth_dir = config.data_dir / "synth"
    by_scenario: dict[str, list[tuple[str, MotionClip, int]]] = {s: [] for s in config.scenarios}
    if synth_dir.is_dir() and any(synth_dir.glob("*.npz")):
        for path in split_files(synth_dir).test:
            if all(len(found) >= wanted for found in by_scenario.values()):
                break
            clip, number = MotionClip.load(path), path.stem.split("_")[0]
            if clip.scenario in by_scenario and len(by_scenario[clip.scenario]) < wanted:
                seed = int(number) if number.isdigit() else len(by_scenario[clip.scenario])
                by_scenario[clip.scenario].append((f"{clip.scenario}/{number}", clip, seed))
        source = f"test split of {_shown(synth_dir)}"
    else:
        for seed in RESERVED_TEST_SEEDS:
            scenario = SCENARIOS[seed % len(SCENARIOS)]
            if scenario in by_scenario and len(by_scenario[scenario]) < wanted:
                by_scenario[scenario].append((f"{scenario}/{seed:06d}", synthesize(scenario, seed, config.fps), seed))
        source = (f"synthesized afresh (no data/synth) with the reserved test seeds "
                  f"{RESERVED_TEST_SEEDS.start}-{RESERVED_TEST_SEEDS.stop - 1}")
    # Interleave scenarios so that any prefix of the list covers them evenly.
    scenes = [by_scenario[s][i] for i in range(wanted) for s in config.scenarios if i < len(by_scenario[s])]
    return scenes, source


def held_out_real(config: ProtocolConfig) -> tuple[MotionClip | None, str]:
    """The held-out salsa pair as one clip (or None), and where it came from."""
    lead, follow = HELD_OUT_SALSA_TAKES[0].split("/")
    npz = config.data_dir / "salsa" / f"{lead}_{follow}.npz"
    if npz.exists():
        return MotionClip.load(npz), _shown(npz)
    bvh = [config.shared_dir / "cmu_salsa" / f"{take}.bvh" for take in (lead, follow)]
    if all(p.exists() for p in bvh):
        from ..io.importer import ImportConfig, import_bvh
        clip, _ = import_bvh(bvh, ImportConfig(fps=config.fps))
        return clip, f"imported from {bvh[0].name} + {bvh[1].name}"
    return None, f"held-out salsa take {lead}/{follow} not found (neither {npz.name} nor the BVH files)"


def _shown(path: Path) -> str:
    """A path as the report shows it: relative to the repository when inside it."""
    return str(path.relative_to(REPO_ROOT) if path.is_relative_to(REPO_ROOT) else path)


def _item(item_id: str, group: str, clip: MotionClip, noise: float, seed: int, config: ProtocolConfig) -> BenchItem:
    return BenchItem(item_id, group, noise, sketchify(clip, config.keyframes, noise, seed), clip)


def build_protocols(config: ProtocolConfig = ProtocolConfig()) -> list[Protocol]:
    scenes, source = held_out_scenes(config)
    chosen = scenes[:config.per_scenario * len(config.scenarios)]      # interleaved: per_scenario of each
    sketch_only = Protocol("sketch-only", "Held-out synthesized scenes, sketch only (noise 0)",
                           [_item(i, c.scenario, c, 0.0, seed, config) for i, c, seed in chosen],
                           [f"Scenes: {source}; {len(chosen)} storyboards, {config.keyframes} keyframes, "
                            f"sketch seed = scene seed."])
    noisy = scenes[:config.noise_scenes]
    noise = Protocol("noise", "Noise robustness (same scenes, rougher sketches)",
                     [_item(i, c.scenario, c, level, seed, config) for level in config.noise_levels
                      for i, c, seed in noisy],
                     [f"{len(noisy)} scenes x noise {', '.join(f'{n:g}' for n in config.noise_levels)}; "
                      f"3D errors are against the clean held-out clip."])
    real_clip, real_source = held_out_real(config)
    items = []
    if real_clip is not None:
        starts = range(config.real_trim, real_clip.num_frames - config.window + 1, config.real_stride)
        for start in list(starts)[:config.real_windows]:
            window = real_clip.slice(start, start + config.window)
            items.append(_item(f"salsa/{start:04d}", "salsa", window, 0.0, start, config))
    real = Protocol("real", "Held-out real pairs (CMU salsa take 10, two people, no object)", items,
                    [f"Source: {real_source}; {len(items)} windows of {config.window} frames."
                     + ("" if items else " Protocol skipped.")])
    drawn = scenes[:config.artist_scenes]
    artist = Protocol("artist", "Drawn the way artists draw (by hand, and posed with the app's tools)",
                      [BenchItem(f"{i} {kind}", kind, 0.0,
                                 make(sketchify(c, config.keyframes, 0.0, seed), seed + config.drawing, config.artist), c)
                       for i, c, seed in drawn for kind, make in ARTIST_KINDS.items()],
                      [f"{len(drawn)} scenes x {', '.join(ARTIST_KINDS)} (engine.artist_sketch: figures stretched "
                       f"up to 12%, joints 2-3 cm off, spine and collars often unplaced, keys and contact spans "
                       f"a few frames off, strokes of 8-20 points, boxes as four corners; or the canvas's "
                       f"standing template with the end effectors dragged); 3D errors against the clean clip."])
    text = Protocol("sketch+text", "Sketch + text (the sketch-only scenes with a caption of the clip as text)",
                    [BenchItem(i, c.scenario, level, replace(sketchify(c, config.keyframes, level, seed),
                                                             text=caption(c, np.random.default_rng(seed))), c)
                     for level in config.text_noise for i, c, seed in chosen],
                    [f"{len(chosen)} scenes x noise {', '.join(f'{n:g}' for n in config.text_noise)}, each with "
                     f"a caption written from its held-out clip (engine.synth.captions); R-text@3 and MM Dist "
                     f"rank the generated motion against those captions (engine.evaluation.text_motion)."])
    return [sketch_only, noise, real, artist, text]
