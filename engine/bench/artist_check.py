"""`python -m engine.bench.artist_check`: the keepable-motion bounds on many artist-style storyboards.

`bench` scores 10 (quick) or 20 artist-style storyboards, the ones the finishing was tuned on;
at c6a022e, 60 further ones failed far more often (grips within 3 cm: 20 of 20 against 51 of 60).
This check generates Ours (seed 0, or --seed) on scenes `--first` to `--first + --scenes` of the held-out
scenes, drawn both ways (engine.artist_sketch; `--drawing` draws them otherwise: the seeds bench
draws with are the ones the finishing was tuned on, and at 8e79477 another drawing of the same 50
scenes popped over 5 cm in 19 of 100 storyboards against 12; `--harsh` draws them more roughly,
artist_sketch.HARSH), and prints, for each of ANIMATOR_TARGETS, how many
storyboards meet it, the mean and the worst, and how far the held object drops where a hand lets
go of it for good (the held-out motion sets it down), and what Wrist@key is made of
(wrist_key_parts), how many pop by a jump beyond both neighbouring steps alone (largest_jump:
the issue's wording; Pop also counts spikes), and how far a held object is from its drawn path
and outlines (held_off_drawing). About 0.4 s a storyboard on 2 cores.
"""
from __future__ import annotations

import argparse

import numpy as np

from ..artist_sketch import HARSH, ArtistConfig
from ..controls import base_path
from ..finishing import lasting_as_long
from ..finishing.contacts import ContactConfig
from ..finishing.held import drawn_in_hands, sketched_rest, true_spans
from ..finishing.steady import step_jumps
from ..generate import generate
from ..geometry.polylines import point_polyline_distance
from ..models.bundle import load_default
from ..sampling.config import sampler_config
from .animator import ANIMATOR_TARGETS, WRISTS
from .protocol import ProtocolConfig, build_protocols
from .runner import sample_metrics

DROP = 0.05   # m above its rest at a release: dropped, not put down


def release_drops(clip, storyboard) -> list[float]:
    """How high (m) above its lowest the first object is at each last frame of a hold that ends
    before the clip does, unless it ends within the finishing's lift_frames (ContactConfig, at the
    clip's rate) of the end with no resting place sketched after it but where it is held: held.py
    carries such a hold on to the end, the hands on the grips (the artist's span a few frames off),
    as the held-out motion holds it (all three "drops" over 5 cm at cd3455e on scenes 0-49,
    drawing 0)."""
    if clip.obj_pose is None or not storyboard.objects:
        return []
    pose = np.asarray(clip.obj_pose, float)
    height = pose[:, 0, 1]
    carried_on = lasting_as_long(ContactConfig(), clip.fps).lift_frames
    held = np.zeros(len(height), bool)
    for c in storyboard.contacts:
        if c.object == storyboard.objects[0].id:
            held[c.start:c.end + 1] = True
    last, spec = len(height) - 1, storyboard.objects[0].spec

    def carried_to_the_end(end: int) -> bool:   # as held.py's _hold_one decides
        rest = sketched_rest(storyboard, 0, end + 1, last)
        return last - end < carried_on and (rest is None or drawn_in_hands(rest, pose[end, 0, :3], spec, storyboard.camera))

    return [float(height[end] - height.min()) for _, end in true_spans(held) if end < last and not carried_to_the_end(end)]


def largest_jump(joints: np.ndarray) -> float:
    """The largest step of a joint beyond both of its neighbouring steps (m), joints (N, H, 22, 3):
    issue 18's "pop beyond both neighbours", Pop without its spikes (a joint off the line between
    its neighbouring frames)."""
    return float(max(step_jumps(joints.reshape(len(joints), -1, 3)).max(initial=0.0), 0.0))


def wrist_key_parts(joints: np.ndarray, reference: np.ndarray, storyboard) -> tuple[float, float, float] | None:
    """Means (m) over the wrists the keys place, joints and reference (N, H, 22, 3): how far the
    drawn point is from the held-out wrist in the sketch plane, how far the generated wrist is from
    the drawn point there, and how far the generated wrist is from the held-out one in depth (the
    2D sketch does not give it). None without such a wrist. Wrist@key is 3D against the held-out
    wrist: a drawing off the held-out pose is a miss the generation cannot help."""
    camera, parts = storyboard.camera, []
    back = camera.basis()[2]
    for k in storyboard.keyposes:
        h = storyboard.agent_index(k.agent)
        for j in WRISTS:
            if k.mask[j]:
                made, held_out = joints[k.frame, h, j], reference[k.frame, h, j]
                parts.append((np.linalg.norm(k.points[j] - camera.project(held_out)),
                              np.linalg.norm(camera.project(made) - k.points[j]), abs((made - held_out) @ back)))
    return tuple(np.mean(parts, axis=0)) if parts else None


def held_off_drawing(clip, storyboard) -> tuple[list[float], list[float]]:
    """Where a held object is against what the artist drew of it (m, sketch plane): its base's
    distance to its drawn path (as the finishing reads it: engine.controls.base_path) at every
    held frame of the path's span, and its centre's to the centre of each outline drawn at a
    held frame (engine.finishing.drawn_holds)."""
    if clip.obj_pose is None:
        return [], []
    pose, cam = np.asarray(clip.obj_pose, float), storyboard.camera
    held = np.zeros((len(pose), len(storyboard.objects)), bool)
    for c in storyboard.contacts:
        if c.object is not None:
            held[c.start:c.end + 1, storyboard.object_index(c.object)] = True
    path_offs, outline_offs = [], []
    for p in storyboard.object_paths:
        o = storyboard.object_index(p.object)
        frames = p.start + np.flatnonzero(held[p.start:p.end + 1, o])
        path_offs += point_polyline_distance(cam.project(pose[frames, o, :3]), base_path(storyboard, p)).tolist()
    for k in storyboard.object_keys:
        o = storyboard.object_index(k.object)
        if held[k.frame, o]:
            centre = pose[k.frame, o, :3] + (0.0, storyboard.objects[o].spec.size[1] / 2, 0.0)
            outline_offs.append(float(np.linalg.norm(cam.project(centre) - (k.outline.min(0) + k.outline.max(0)) / 2)))
    return path_offs, outline_offs


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--first", type=int, default=20, help="first held-out scene (bench uses 0-9)")
    parser.add_argument("--scenes", type=int, default=30, help="scenes, each drawn and posed")
    parser.add_argument("--seed", type=int, default=0, help="the generation's seed")
    parser.add_argument("--drawing", type=int, default=0,
                        help="added to each scene's drawing seed: other drawings of the same scenes (bench uses 0)")
    parser.add_argument("--harsh", action="store_true",
                        help="drawn more roughly (engine.artist_sketch.HARSH: 18%% stretch, joints 3-5 cm off)")
    args = parser.parse_args(argv)
    config = ProtocolConfig(per_scenario=1, noise_scenes=0, real_windows=0, artist_scenes=args.first + args.scenes,
                            drawing=args.drawing, artist=HARSH if args.harsh else ArtistConfig())
    artist = next(p for p in build_protocols(config) if p.name == "artist")
    items = artist.items[2 * args.first:]
    bundle, rows, drops, wrists, jumps, off_path, off_outline = load_default(), [], [], [], [], [], []
    for item in items:
        clip = generate(item.storyboard, sampler_config(seed=args.seed), bundle, quiet=True).clips[0]
        rows.append(sample_metrics(clip, item))
        jumps.append(largest_jump(np.asarray(clip.joints, float)))
        drops += release_drops(clip, item.storyboard)
        path_offs, outline_offs = held_off_drawing(clip, item.storyboard)
        off_path, off_outline = off_path + path_offs, off_outline + outline_offs
        wrists.append(wrist_key_parts(np.asarray(clip.joints, float), np.asarray(item.reference.joints, float),
                                      item.storyboard))
    print(f"{len(items)} artist-style storyboards (scenes {args.first}-{args.first + args.scenes - 1}, drawing "
          f"{args.drawing}{', harsh' if args.harsh else ''}), Ours, seed {args.seed}")
    for name, bound in ANIMATOR_TARGETS.items():
        values = np.array([r[name] for r in rows])
        print(f"{name:10s} within {bound:g}: {np.sum(values <= bound):3d}/{len(values)}   "
              f"mean {values.mean():.4f}   worst {values.max():.3f}")
    jumps = np.array(jumps)
    print(f"Pop        of it the jumps beyond both neighbouring steps: within {ANIMATOR_TARGETS['Pop']:g}: "
          f"{np.sum(jumps <= ANIMATOR_TARGETS['Pop']):3d}/{len(jumps)}   mean {jumps.mean():.4f}   worst {jumps.max():.3f}")
    parts = [p for p in wrists if p is not None]
    if parts:
        drawn, placed, depth = np.mean(parts, axis=0)
        print(f"Wrist@key  of it: drawn off the held-out wrist {drawn:.4f} (sketch plane), generated off the "
              f"drawing {placed:.4f}, off the held-out wrist in depth {depth:.4f} (means)")
    if drops:
        print(f"releases   dropped over {DROP:g} m: {np.sum(np.array(drops) > DROP):3d}/{len(drops)}   "
              f"mean {np.mean(drops):.4f}   worst {np.max(drops):.3f}")
    for name, offs, share in (("off path", off_path, 95), ("off outline", off_outline, 90)):
        if offs:
            print(f"held object {name} (sketch plane, {len(offs)} held {'frames' if share == 95 else 'keys'}): "
                  f"mean {np.mean(offs):.4f}   p{share} {np.percentile(offs, share):.4f}   worst {np.max(offs):.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
