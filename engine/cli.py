"""`sketch2colab` command line. Each subcommand parses its options here and imports its
implementation only when run, so that `validate` stays instant and nothing loads torch needlessly.

Exit codes: 0 success, 2 bad input (one-line message on stderr), 1 anything unexpected.
"""
from __future__ import annotations

import argparse
import sys

from .atomic import check_output_path
from .sampling.config import DEFAULT_STEPS


class UserError(Exception):
    """Bad input from the user: printed as one line, exit code 2."""


def cmd_validate(args) -> int:
    from .storyboard import Storyboard
    sb = Storyboard.load(args.file)
    print(f"{args.file}: ok ({len(sb.agents)} agents, {len(sb.objects)} objects, "
          f"{len(sb.keyposes)} keyposes, {len(sb.trajectories)} trajectories, "
          f"{len(sb.contacts)} contacts, {sb.length} frames at {sb.fps:g} fps)")
    return 0


def cmd_sketchify(args) -> int:
    from .clip import MotionClip
    from .sketchify import sketchify
    if not 0.0 <= args.noise <= 1.0:
        raise UserError(f"--noise must be in [0, 1] (0.8 is the roughest training sketch), got {args.noise}")
    if args.keyframes < 0:
        raise UserError(f"--keyframes must be >= 0, got {args.keyframes}")
    check_output_path(args.output)
    clip = MotionClip.load(args.clip)
    if clip.num_frames < 2:
        raise UserError(f"{args.clip}: {clip.num_frames} frame{'s' * (clip.num_frames != 1)}; a storyboard "
                        f"needs a clip of at least 2")
    sb = sketchify(clip, args.keyframes, args.noise, args.seed)
    sb.save(args.output)
    print(f"{args.output}: {len(sb.keyframes())} keyframes, {len(sb.keyposes)} keyposes, "
          f"{len(sb.trajectories)} trajectories, {len(sb.contacts)} contacts")
    return 0


def cmd_import_bvh(args) -> int:
    from .io.bvh import BvhError
    from .io.importer import ImportConfig, import_bvh
    from .io.retarget import RetargetError, load_joint_map
    if len(args.files) > 2:
        raise UserError(f"import-bvh takes one or two BVH files (lead, follow), got {len(args.files)}")
    if not 1.0 <= args.fps <= 240.0:
        raise UserError(f"--fps must be between 1 and 240, got {args.fps:g}")
    check_output_path(args.output)
    try:
        clip, report = import_bvh(args.files, ImportConfig(fps=args.fps), load_joint_map(args.map) if args.map else None)
    except (BvhError, RetargetError) as e:
        raise UserError(str(e)) from None
    clip.save(args.output)
    print(f"{args.output}: {clip.num_humans} people, {clip.num_frames} frames at {clip.fps:g} fps "
          f"(from {report.source_fps:g} fps); {report.summary()}")
    return 0


def cmd_synth(args) -> int:
    from .synth import SCENARIOS, write_dataset
    scenarios = tuple(s.strip() for s in args.scenarios.split(",") if s.strip()) if args.scenarios else SCENARIOS
    unknown = [s for s in scenarios if s not in SCENARIOS]
    if unknown or not scenarios:
        raise UserError(f"unknown scenario {', '.join(unknown) or '(none)'}; choose from {', '.join(SCENARIOS)}")
    if args.clips < 1 or args.fps <= 0 or args.seconds <= 0:
        raise UserError("--clips, --fps and --seconds must be positive")
    try:
        index = write_dataset(args.output, args.clips, args.seed, scenarios, args.fps, args.seconds)
    except ValueError as e:  # e.g. a clip too short for its scenario
        raise UserError(str(e)) from None
    print(f"wrote {args.clips} clips and {index}")
    return 0


def cmd_train(args) -> int:
    from .training.command import TrainError, train_command
    try:
        train_command(args.stage, args.config, args.data, args.real, args.steps, args.resume, args.runs,
                      args.threads, args.from_bundle, args.batch_size, args.lr, args.minutes, args.workers,
                      args.artist_share, args.warm_start, args.text, args.sparse_share)
    except TrainError as e:
        raise UserError(str(e)) from None
    return 0


def cmd_bundle(args) -> int:
    import json
    import shlex

    from .models.bundle import BundleError
    from .training.card import export_baselines, export_default
    command = args.command or "sketch2colab " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    if args.baselines:
        try:
            card = export_baselines(args.runs, args.output or "resources/models/baselines.pt", args.data or [],
                                    args.real or [], args.base, command)
        except (BundleError, FileNotFoundError) as e:
            raise UserError(str(e)) from None
        print(json.dumps(card, indent=1))
        return 0
    card = export_default(args.runs, args.output or "resources/models/default.pt", args.data or [], args.real or [],
                          args.config, command=command)
    print(json.dumps({k: card[k] for k in ("bundle", "size_mb", "load_s", "stages", "held_out")}, indent=1))
    return 0


def _sampler_config(args):
    from .sampling.config import SamplerError, sampler_config
    try:
        return sampler_config(method="student" if args.method == "retrieval" else args.method, steps=args.steps,
                              seed=args.seed, cfg=args.cfg, variations=args.variations, energy=not args.no_energy,
                              ctmc=not args.no_ctmc, finish=not args.no_finish, steady=args.steady,
                              preview=getattr(args, "preview", False), text_cfg=getattr(args, "text_weight", None))
    except SamplerError as e:
        raise UserError(str(e)) from None


def cmd_generate(args) -> int:
    from pathlib import Path

    from .export import check_export_paths, export_requested
    from .generate import generate, print_summary, summary, write_outputs
    from .models.bundle import BundleError, load_bundle, load_default
    from .sampling.config import SamplerError
    from .storyboard import Storyboard
    sb = Storyboard.load(args.storyboard)
    if args.text is not None:
        sb.text = " ".join(args.text.split())
    config = _sampler_config(args)
    Path(args.output).parent.mkdir(parents=True, exist_ok=True)
    check_output_path(args.output)                                # fail before generating, not after
    check_export_paths(args)
    try:
        bundle = None if args.method == "retrieval" else (load_bundle(args.checkpoint) if args.checkpoint
                                                          else load_default())
        result = generate(sb, config, bundle, args.method, log_steps=args.log_steps)
    except (BundleError, SamplerError) as e:
        raise UserError(str(e)) from None
    written = write_outputs(result, Path(args.output))
    try:
        written += export_requested(result.clips[0], args)
    except ValueError as e:  # e.g. --object-csv for a storyboard without an object
        raise UserError(str(e)) from None
    print(f"wrote {', '.join(str(p) for p in written)}", file=sys.stderr)
    for note in result.notes:
        print(f"note: {note}", file=sys.stderr)
    print_summary(summary(result, sb, args.method))
    return 0


def cmd_demo(args) -> int:
    import json

    from .demo import run_demo
    from .sampling.config import sampler_config
    for row in run_demo(args.output, sampler_config(steps=args.steps, seed=args.seed), render=not args.no_render):
        print(json.dumps(row))
    print(f"results in {args.output}/", file=sys.stderr)
    return 0


def build_parser() -> argparse.ArgumentParser:
    from .cpu import ENV_VAR
    from .export import add_export_arguments
    p = argparse.ArgumentParser(prog="sketch2colab", description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    computes = argparse.ArgumentParser(add_help=False)   # the commands that run torch
    computes.add_argument("--threads", type=int, metavar="N",
                          help=f"torch CPU threads (default: the cores other programs leave free, re-measured "
                               f"as the run goes on; also settable as {ENV_VAR}=N)")

    s = sub.add_parser("validate", help="check a storyboard JSON file")
    s.add_argument("file")
    s.set_defaults(func=cmd_validate)

    s = sub.add_parser("sketchify", help="draw a storyboard from a motion clip NPZ")
    s.add_argument("clip")
    s.add_argument("-o", "--output", required=True, help="storyboard JSON to write")
    s.add_argument("--keyframes", type=int, default=4, help="keyframes to draw (default 4)")
    s.add_argument("--noise", type=float, default=0.0, help="hand-drawn roughness, 0 = exact (0-0.8)")
    s.add_argument("--seed", type=int, default=0, help="camera, path choices and stroke noise")
    s.set_defaults(func=cmd_sketchify)

    s = sub.add_parser("import-bvh", help="import one or two synchronized BVH takes as a motion clip NPZ")
    s.add_argument("files", nargs="+", metavar="BVH", help="lead BVH, then optionally the follow's")
    s.add_argument("-o", "--output", required=True, metavar="CLIP.npz")
    s.add_argument("--fps", type=float, default=20.0, help="output frame rate (default 20)")
    s.add_argument("--map", default=None,
                   help="joint map: built-in cmu_salsa or smpl22, or a JSON file (default: the built-in "
                        "whose joints the file has)")
    s.set_defaults(func=cmd_import_bvh)

    s = sub.add_parser("synth", help="write procedural two-person scenes as motion clips")
    s.add_argument("-o", "--output", required=True, help="output folder (clips + index.json)")
    s.add_argument("--clips", type=int, default=10)
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--scenarios", default="", help="comma-separated subset (default: all)")
    s.add_argument("--fps", type=float, default=20.0)
    s.add_argument("--seconds", type=float, default=6.0)
    s.set_defaults(func=cmd_synth)

    s = sub.add_parser("train", parents=[computes],
                       help="train a model stage (or all) on clip folders; torchrun for several GPUs")
    s.add_argument("stage", choices=["vqvae", "encoders", "teacher", "student1", "student2", "potential",
                                     "ctmc", "surrogate", "preview", "all", "sketch2anim", "controlnet1", "controlnet2"],
                   help="a stage of the model, all of them in order, or a benchmark baseline's "
                        "(sketch2anim: Sketch2Anim-INT; controlnet1, controlnet2: the parallel-ControlNets ablation)")
    s.add_argument("--config", choices=["default", "large"], default="default",
                   help="default: 2-core CPU sizes; large: GPU sizes and paper settings")
    s.add_argument("--data", nargs="+", metavar="DIR", help="folders of synthesized clip NPZs")
    s.add_argument("--real", nargs="+", metavar="DIR", help="folders of imported capture clip NPZs")
    s.add_argument("--steps", type=int, help="steps per stage (overrides the config)")
    s.add_argument("--resume", action="store_true", help="continue from runs/STAGE/checkpoint.pt")
    s.add_argument("--batch-size", type=int, metavar="N", help="clips per step (overrides the config)")
    s.add_argument("--lr", type=float, help="learning rate of every stage (overrides the config)")
    s.add_argument("--minutes", type=float, metavar="M",
                   help="stop each stage after M minutes, saved like a finished one; --resume goes on")
    s.add_argument("--workers", type=int, metavar="N",
                   help="processes that draw the storyboards (overrides the config; a GPU waits on them without)")
    s.add_argument("--artist-share", type=float, default=0.0, metavar="P",
                   help="share of training storyboards redrawn the way artists draw (engine.artist_sketch)")
    s.add_argument("--warm-start", action="store_true",
                   help="start from the stage's own runs/STAGE/final.pt (fine-tune; with --from-bundle, the shipped one)")
    s.add_argument("--sparse-share", type=float, default=0.0, metavar="P",
                   help="share of training storyboards cut to their first and last keyposes (the text says the rest)")
    s.add_argument("--text", action="store_true",
                   help="the model reads the storyboard's text too (trained on the synthesizer's captions)")
    s.add_argument("--runs", default="runs", help="output root (default runs/)")
    s.add_argument("--from-bundle", metavar="BUNDLE.pt",
                   help="take the earlier stages a stage needs from this bundle where runs/ lacks them "
                        "(e.g. train the preview on the shipped bundle)")
    s.set_defaults(func=cmd_train)

    s = sub.add_parser("bundle", help="collect trained stages into a model bundle with its model card")
    s.add_argument("--runs", default="runs", help="training output root (default runs/)")
    s.add_argument("-o", "--output", help="default: resources/models/default.pt (baselines.pt with --baselines)")
    s.add_argument("--baselines", action="store_true",
                   help="collect the benchmark's baselines (stages sketch2anim, controlnet1/2) instead, for --base")
    s.add_argument("--base", metavar="BUNDLE.pt", help="with --baselines: the bundle they were trained with "
                                                       "(default: the shipped one)")
    s.add_argument("--data", nargs="+", metavar="DIR", help="synthesized clip folders (their test split is measured)")
    s.add_argument("--real", nargs="+", metavar="DIR", help="imported capture folders (held-out takes are measured)")
    s.add_argument("--config", choices=["default", "large"], default="default")
    s.add_argument("--command", help="the training command to record in the model card")
    s.set_defaults(func=cmd_bundle)

    s = sub.add_parser("generate", parents=[computes], help="generate motion for a storyboard")
    s.add_argument("storyboard")
    s.add_argument("-o", "--output", required=True, metavar="MOTION.npz")
    s.add_argument("--steps", type=int, default=DEFAULT_STEPS,
                   help=f"solver steps (default {DEFAULT_STEPS}; DDIM steps for teacher-ddim)")
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--cfg", type=float, default=1.6, help="classifier-free guidance weight (default 1.6)")
    s.add_argument("--method", choices=["student", "teacher-ddpm", "teacher-ddim", "retrieval"], default="student")
    s.add_argument("--text", metavar="WORDS", help="what happens, in words, instead of the storyboard's own text "
                                                   "(\"\" for none)")
    s.add_argument("--text-weight", type=float, metavar="W",
                   help="the text's own guidance weight: higher follows the words more where the sketch leaves "
                        "room (default: --cfg's; a third more network time)")
    s.add_argument("--no-energy", action="store_true", help="no energy guidance (ablation)")
    s.add_argument("--no-ctmc", action="store_true", help="no CTMC phase planning (ablation)")
    s.add_argument("--no-finish", action="store_true",
                   help="keep the sampler's raw decode (no finishing pass: keyposes, paths, contacts, feet)")
    s.add_argument("--preview", action="store_true",
                   help="the fast path an artist sees while dragging: the preview student's few jumps, "
                        "no energy guidance, finished without the clean-up (keys, paths, feet, grips exact)")
    s.add_argument("--steady", action="store_true",
                   help="damped guidance: a small stroke edit changes the motion a little, not into a new "
                        "take (feet skate more)")
    s.add_argument("--variations", type=int, default=1, help="K variations in one batch")
    add_export_arguments(s)  # --npz, --bvh-dir, --object-csv, --glb of the first variation
    s.add_argument("--checkpoint", metavar="BUNDLE.pt", help="model bundle (default: the shipped one)")
    s.add_argument("--log-steps", action="store_true", help="one line per solver step instead of a bar")
    s.set_defaults(func=cmd_generate)

    s = sub.add_parser("demo", parents=[computes], help="run the bundled example storyboards headless; contact sheets and GIFs")
    s.add_argument("-o", "--output", default="demo_out")
    s.add_argument("--steps", type=int, default=DEFAULT_STEPS)
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--no-render", action="store_true", help="skip the contact sheets and GIFs")
    s.set_defaults(func=cmd_demo)
    s = sub.add_parser("bench", parents=[computes], help="benchmark every method on held-out storyboards (writes BENCHMARKS.md)")
    s.add_argument("--quick", action="store_true", help="small subset, under 5 minutes on 2 cores")
    s.add_argument("-o", "--output", default="BENCHMARKS.md", metavar="BENCHMARKS.md")
    s.add_argument("--json", metavar="FILE", help="also write every figure as JSON")
    s.add_argument("--checkpoint", metavar="BUNDLE.pt", help="model bundle (default: the shipped one)")
    s.add_argument("--baselines", metavar="BASELINES.pt",
                   help="trained baselines for the bundle (default: resources/models/baselines.pt with the shipped one)")
    s.set_defaults(func=cmd_bench)
    return p


def cmd_bench(args) -> int:
    from .bench.command import BenchError, bench_command
    for path in (args.output, args.json):
        if path:
            check_output_path(path)
    try:
        bench_command(args.quick, args.output, args.json, args.checkpoint, args.baselines)
    except BenchError as e:
        raise UserError(str(e)) from None
    return 0


def _set_threads(threads: int | None) -> None:
    """--threads N becomes the process's override (engine.cpu reads it), for every layer alike."""
    import os

    from .cpu import ENV_VAR, threads_override
    if threads is not None:
        if threads < 1:
            raise UserError(f"--threads must be at least 1, got {threads}")
        os.environ[ENV_VAR] = str(threads)
    try:
        threads_override()
    except ValueError as e:
        raise UserError(str(e)) from None


def main(argv: list[str] | None = None) -> int:
    from .clip import ClipError
    from .storyboard import StoryboardError

    args = build_parser().parse_args(argv)
    try:
        _set_threads(getattr(args, "threads", None))
        return args.func(args) or 0
    except (UserError, StoryboardError, ClipError, OSError) as e:  # OSError: missing files, permissions
        print(f"error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
