"""`sketch2colab` command line. Each subcommand parses its options here and imports its
implementation only when run, so that `validate` stays instant and nothing loads torch needlessly.

Exit codes: 0 success, 2 bad input (one-line message on stderr), 1 anything unexpected.
"""
from __future__ import annotations

import argparse
import sys


class UserError(Exception):
    """Bad input from the user: printed as one line, exit code 2."""


def cmd_validate(args) -> int:
    from .storyboard import Storyboard
    sb = Storyboard.load(args.file)
    print(f"{args.file}: ok ({len(sb.agents)} agents, {len(sb.objects)} objects, "
          f"{len(sb.keyposes)} keyposes, {len(sb.trajectories)} trajectories, "
          f"{len(sb.contacts)} contacts, {sb.length} frames at {sb.fps:g} fps)")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="sketch2colab", description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    s = sub.add_parser("validate", help="check a storyboard JSON file")
    s.add_argument("file")
    s.set_defaults(func=cmd_validate)
    return p


def main(argv: list[str] | None = None) -> int:
    from .clip import ClipError
    from .storyboard import StoryboardError

    args = build_parser().parse_args(argv)
    try:
        return args.func(args) or 0
    except (UserError, StoryboardError, ClipError, FileNotFoundError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
