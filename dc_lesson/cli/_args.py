"""What every subcommand of ``dc-lesson`` shares: the argument types (a size of 0 or below is
an error, never a request for the default), the one-line parser, the usage error, the command
line written into results, and the output check that runs before any compute."""

from __future__ import annotations

import argparse
import math
import shlex
import sys

# The options of ``perf``, by the name argparse gives them.
OPTIONS = {"tasks": "--tasks", "steps": "--steps", "seeds": "--seeds", "before": "--before",
           "variant": "--variant"}


class UsageError(ValueError):
    """A combination of options the command does not take."""


class Parser(argparse.ArgumentParser):
    """argparse with a one-line refusal: the error and where the help is (no usage dump)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see: {self.prog} -h)\n")


def command_line() -> str:
    return "dc-lesson " + " ".join(shlex.quote(a) for a in sys.argv[1:])


def _whole_number(minimum: int, what: str):
    """An argparse type: a whole number of at least ``minimum``."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be a whole number, got {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"{what} {minimum}{' or more' if minimum == 0 else ''}"
                                             f", got {value}")
        return value
    return parse

positive_int = _whole_number(1, "must be at least")

seed_int = _whole_number(0, "a seed must be")


def positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a positive finite number, got {text}")
    return value


def check_output(path, folder: bool = False):
    """An output path is checked before any compute (it would be lost at the end otherwise)."""
    from dc_lesson.storage import check_writable
    return None if path is None else check_writable(path, folder=folder)


def refuse_unused(what: str, table: dict, args, command: str) -> None:
    """An option the command's ``what`` does not read is refused, never ignored."""
    used = table[what][1]
    given = [OPTIONS[k] for k in OPTIONS
             if getattr(args, k, None) is not None and k not in used]
    if given:
        raise UsageError(f"{command} {what} does not take {', '.join(given)}; it reads "
                         f"{', '.join(OPTIONS[k] for k in OPTIONS if k in used) or 'only --out'}")
    if args.tasks is not None and not args.tasks:
        raise UsageError("--tasks needs at least one task name (leave it out for the "
                         "default tasks)")
