"""The ``gaide`` command line. Errors print one line and exit with the stage's code.

Whatever goes wrong, the command prints one line on stderr and exits non-zero: the project's
own errors with their stage's code (see the README's table), a bad flag with 2, an input or
output the operating system refuses (a full disk, a folder without write permission) with 9,
Ctrl-C with 130, and anything unforeseen with 1 and a request to report it (``-v`` shows the
traceback). The command modules are imported inside that net, so an interrupt while they
load is one line too.
"""

from __future__ import annotations

import _thread
import argparse
import contextlib
import logging
import signal
import sys
import threading
import time
import traceback
from collections.abc import Iterator
from types import CodeType, FrameType
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
    with _ctrl_c_after_imports():
        code = _main(argv)
    _forget_escaped_interrupts()
    return code


def _forget_escaped_interrupts() -> None:
    """Let the exit code ``main`` returns be the process's, even after a handled Ctrl-C.

    CPython notes every KeyboardInterrupt that escapes code run from a string (``exec`` of
    source: rosbags registers a bag's message types so, and ``dataclasses`` and
    ``collections.namedtuple`` make functions so), and ``python -m`` then ends the process
    by SIGINT at exit, caught or not. ``python -m gaide demo`` interrupted while rosbags ran
    such code (about 4 s in) printed its one line, then died by SIGINT instead of exiting
    with 130. CPython clears that note each time it starts running source from a string, so
    running an empty one clears it (so since 3.8, which brought the note; no public call
    does it)."""
    exec("")


def _main(argv: list[str] | None) -> int:
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


@contextlib.contextmanager
def _ctrl_c_after_imports() -> Iterator[None]:
    """Ctrl-C raises KeyboardInterrupt, except while a module loads: there it waits for the
    import to end. The commands import their libraries when they need them, and a C
    extension interrupted in its initialization fails with an ImportError, which some
    libraries take for "optional feature missing" and go on: the interrupt would be lost
    (the run finishing with 0) or turn into an internal error.

    An interrupt that lands in a finalizer (a ``__del__`` or a weak reference's callback,
    which the garbage collector runs in the middle of any code) is one Python prints and
    drops: it is delivered again, to whatever runs next.

    A process started with Ctrl-C ignored (a script's background job, which the shell starts
    so, so that Ctrl-C stops the script's foreground command only) keeps ignoring it."""
    ignored = signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    if ignored or threading.current_thread() is not threading.main_thread():
        yield
        return
    held = threading.Event()

    def must_wait(frame: FrameType | None) -> bool:
        return _importing(frame) or _inside(frame, on_unraisable.__code__)

    def release_when_free() -> None:
        main_id = threading.main_thread().ident
        while must_wait(sys._current_frames().get(main_id or 0)):
            time.sleep(0.05)
        held.clear()
        _thread.interrupt_main()  # calls the handler again, now where it can raise

    def hold() -> None:
        if not held.is_set():
            held.set()
            threading.Thread(target=release_when_free, daemon=True).start()

    def on_sigint(signum: int, frame: FrameType | None) -> None:
        if not must_wait(frame):
            raise KeyboardInterrupt
        hold()

    def on_unraisable(unraisable: Any) -> None:
        if isinstance(unraisable.exc_value, KeyboardInterrupt):
            hold()
        else:
            previous_hook(unraisable)

    previous_hook = sys.unraisablehook
    previous = signal.signal(signal.SIGINT, on_sigint)
    sys.unraisablehook = on_unraisable
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        sys.unraisablehook = previous_hook


def _importing(frame: FrameType | None) -> bool:
    """Is ``frame`` (or a caller of it) loading a module?"""
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib"):
            return True
        frame = frame.f_back
    return False


def _inside(frame: FrameType | None, code: CodeType) -> bool:
    """Is ``frame`` (or a caller of it) running ``code``?"""
    while frame is not None:
        if frame.f_code is code:
            return True
        frame = frame.f_back
    return False


def _say(command: str, text: str) -> None:
    print(f"{command}: {text}".replace("\n", " "), file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
