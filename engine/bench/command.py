"""`sketch2colab bench`: run the suite, write BENCHMARKS.md (+ JSON and diagnostic PNGs)."""
from __future__ import annotations

import sys
from pathlib import Path

FIGURES_DIR = "bench_figures"          # beside the Markdown report


class BenchError(ValueError):
    """Bad input (a checkpoint or evaluator that cannot be read): one line for the user."""


def command_line(quick: bool, output: str, json_path: str | None, checkpoint: str | None,
                 baselines: str | None = None) -> str:
    """The exact command that reproduces a report, for its header."""
    parts = ["sketch2colab bench"] + (["--quick"] if quick else []) + ["-o", output]
    parts += ["--json", json_path] if json_path else []
    parts += ["--checkpoint", checkpoint] if checkpoint else []
    parts += ["--baselines", baselines] if baselines else []
    return " ".join(parts)


def bench_command(quick: bool, output: str, json_path: str | None = None, checkpoint: str | None = None,
                  baselines: str | None = None) -> dict:
    """`baselines`: the trained baselines' file (default: resources/models/baselines.pt where it
    exists, for the shipped bundle); methods whose part is not there are left out, with a note."""
    from ..evaluation.evaluator import DEFAULT_PATH, EvaluatorError, load_evaluator
    from ..evaluation.text_motion import TEXT_PATH, load_text_embedder
    from ..models.bundle import BASELINES_PATH, BundleError, load_baselines, load_bundle, load_default
    from .report import write
    from .suite import BenchConfig, run_bench
    try:
        bundle = load_bundle(checkpoint) if checkpoint else load_default()
        shipped = str(BASELINES_PATH) if checkpoint is None and BASELINES_PATH.is_file() else None
        if baselines or shipped:   # the shipped file is found, not written into the report's command
            bundle = load_baselines(bundle, baselines or shipped)
        evaluator = load_evaluator(DEFAULT_PATH) if DEFAULT_PATH.is_file() else None
        text_embedder = load_text_embedder(TEXT_PATH) if evaluator is not None and TEXT_PATH.is_file() else None
    except (BundleError, EvaluatorError) as e:
        raise BenchError(str(e)) from None
    markdown = Path(output)
    results = run_bench(bundle, BenchConfig.quick() if quick else BenchConfig.full(), evaluator,
                        markdown.parent / FIGURES_DIR, text_embedder=text_embedder)
    write(results, command_line(quick, output, json_path, checkpoint, baselines), markdown,
          Path(json_path) if json_path else None)
    print(f"wrote {output}{' and ' + json_path if json_path else ''} in {results['elapsed_s']:.0f} s", file=sys.stderr)
    return results
