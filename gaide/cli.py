"""The ``gaide`` command line. Errors print one line and exit with the stage's code.

Whatever goes wrong, the command prints one line on stderr and exits non-zero: the project's
own errors with their stage's code (see the README's table), a bad flag with 2, an input or
output the operating system refuses (a full disk, a folder without write permission) with 9,
Ctrl-C with 130, and anything unforeseen with 1 and a request to report it (``-v`` shows the
traceback). The command modules are imported inside that net, so an interrupt while they
load is one line too.
"""

from __future__ import annotations

import argparse
import logging
import sys
import traceback
from typing import Any, NoReturn

from gaide_core.errors import GaideError

#: Exit code for an input or output the operating system refused.
OS_ERROR_EXIT = 9


class Parser(argparse.ArgumentParser):
    """argparse with a one-line error (and exit code 2) instead of the usage block."""

    def error(self, message: str) -> NoReturn:
        print(f"{self.prog}: error: {message} (see {self.prog} --help)", file=sys.stderr)
        raise SystemExit(2)


def build_parser() -> argparse.ArgumentParser:
    from gaide import demo
    from gaide.commands import bench, execution, neural, perception, record, robot, run, scenes

    parser = Parser(prog="gaide", description=__doc__.split("\n\n")[0])
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress details")
    sub = parser.add_subparsers(dest="command", required=True)
    for module in (demo, record, perception, robot, scenes, bench, neural, execution, run):
        module.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    command = "gaide"
    args: Any = None
    try:
        try:
            args = build_parser().parse_args(argv)
        except SystemExit as done:  # --help (0) or a bad flag (2, already said)
            return int(done.code or 0)
        command = f"gaide {args.command}"
        logging.basicConfig(
            level=logging.INFO if args.verbose else logging.WARNING,
            format="%(levelname)s %(name)s: %(message)s",
        )
        return int(args.func(args))
    except GaideError as err:
        _say(command, f"error: {err}")
        return err.exit_code
    except KeyboardInterrupt:
        _say(command, "interrupted")
        return 130
    except OSError as err:  # not translated by the stage that met it
        where = f": {err.filename}" if err.filename else ""
        _say(command, f"error: {err.strerror or err}{where}")
        return OS_ERROR_EXIT
    except MemoryError:
        _say(command, "error: out of memory (lower the sizes in the settings or the inputs)")
        return 1
    except Exception as err:  # the last net: a bug, reported in one line
        if args is not None and getattr(args, "verbose", False):
            traceback.print_exc()
        _say(
            command,
            f"internal error: {type(err).__name__}: {err} (please report it; -v shows the "
            "traceback)",
        )
        return 1


def _say(command: str, text: str) -> None:
    print(f"{command}: {text}".replace("\n", " "), file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
