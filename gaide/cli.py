"""The ``gaide`` command line. Errors print one line and exit with the stage's code."""

from __future__ import annotations

import argparse
import logging
import sys

from core.errors import GaideError
from gaide import demo
from gaide.commands import bench, execution, neural, perception, record, robot, run, scenes


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="gaide", description=__doc__)
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress details")
    sub = parser.add_subparsers(dest="command", required=True)
    demo.add_parser(sub)
    record.add_parser(sub)
    perception.add_parser(sub)
    robot.add_parser(sub)
    scenes.add_parser(sub)
    bench.add_parser(sub)
    neural.add_parser(sub)
    execution.add_parser(sub)
    run.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    try:
        return int(args.func(args))
    except GaideError as err:
        print(f"gaide {args.command}: error: {err}", file=sys.stderr)
        return err.exit_code
    except KeyboardInterrupt:
        print(f"gaide {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
