"""Argument types and the parser shared by the command-line tools (bpy-free): every bad
argument gives one line on stderr and exit code 2."""

from __future__ import annotations

import argparse
import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from .render_settings import check_side


class OneLineParser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are one line (no usage block) and exit with 2."""

    def error(self, message: str):
        if message.endswith(("expected one argument", "expected at least one argument")):
            # a missing value, or one starting with '-' (argparse reads --resolution -64x48 as an option)
            message += " (no value given? a value that starts with '-' must be written --option=VALUE)"
        print(f"error: {message} (see {self.prog} --help)", file=sys.stderr)
        sys.exit(2)


@dataclass(frozen=True)
class Option:
    """A command-line option that a registered part declares beside its code (an executor's
    ``--ray-address``, an export's ``--colmap-text``): ``flag``, its ``help``, and argparse's
    ``type`` (a parser of the text, e.g. :func:`int_at_least`), ``action`` (e.g.
    ``"store_true"``) and ``default``. Its value is ``args.<dest>``."""

    flag: str
    help: str
    type: Callable[[str], object] | None = None
    action: str | None = None
    default: object = None

    @property
    def dest(self) -> str:
        """The attribute argparse stores the value in: ``--ray-address`` -> ``ray_address``."""
        return self.flag.lstrip("-").replace("-", "_")

    def add_to(self, parser: argparse.ArgumentParser) -> None:
        keywords = {k: v for k, v in (("type", self.type), ("action", self.action)) if v is not None}
        parser.add_argument(self.flag, help=self.help, default=self.default, **keywords)


def out_folder(text: str) -> Path:
    """An argparse type: a folder path, not empty (an empty one would be the current folder)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("must name a folder, got an empty path")
    return Path(text)


def check_out_folder(parser: argparse.ArgumentParser, out: Path, flag: str = "--out") -> None:
    """``parser.error`` unless ``out`` can be an output folder: not an existing file, not
    inside a seed folder of python -m generator (which only the generator writes)."""
    if os.path.lexists(out) and not out.is_dir():
        parser.error(f"{flag} {out} exists and is not a folder; name a folder")
    from exporters.manifest import seed_folder_containing

    try:
        inside = seed_folder_containing(out)
    except OSError as exc:
        parser.error(f"{flag} {out}: cannot look at it ({exc.strerror}); choose another folder")
    if inside is not None:
        parser.error(f"{flag} {out} is inside the seed folder {inside}, which only python -m generator writes; "
                     "choose a folder outside it")


def int_at_least(minimum: int, what: str, maximum: int | None = None):
    """An argparse type: an integer >= ``minimum`` (and <= ``maximum`` when given)."""
    bound = f">= {minimum}" if maximum is None else f"from {minimum} to {maximum}"

    def parse(text: str) -> int:
        try:
            value = int(text) if len(text) < 100 else None
        except ValueError:
            value = None
        if value is None or value < minimum or (maximum is not None and value > maximum):
            raise argparse.ArgumentTypeError(f"{what} must be an integer {bound}, got {text[:40]!r}")
        return value

    return parse


def positive_float(what: str = "a positive number", zero: bool = False, at_least: float = 0.0):
    """An argparse type: a finite number > 0 (>= 0 with ``zero``), and >= ``at_least``."""

    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            v = math.nan
        if not ((v >= 0 if zero else v > 0) and v >= at_least and math.isfinite(v)):
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
        return v + 0.0  # -0 as 0

    return parse


def coefficients(text: str) -> tuple[float, ...]:
    """An argparse type: comma-separated finite numbers (a lens's distortion coefficients)."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = (math.nan,)
    if not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"expected comma-separated finite numbers such as -0.1,0.02,0,0, got {text!r}")
    return tuple(v + 0.0 for v in values)


def exposure(text: str) -> str | float:
    """An argparse type: 'auto', 'as-rendered' or a number of stops from -10 to 10."""
    if text in ("auto", "as-rendered"):
        return text
    try:
        value = float(text) if len(text) < 40 else math.nan
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and -10 <= value <= 10):
        raise argparse.ArgumentTypeError(f"exposure must be auto, as-rendered or a number of stops from -10 to 10, "
                                         f"got {text[:40]!r}")
    return value + 0.0


def resolution(text: str) -> tuple[int, int]:
    """WxH in pixels, each side as render_settings.check_side allows."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        w = h = 0
    if w <= 0 or h <= 0:
        raise argparse.ArgumentTypeError(f"resolution must be WxH with positive integers, e.g. 640x480; got {text!r}")
    try:
        return check_side("resolution width", w), check_side("resolution height", h)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def first_repeated(values) -> object | None:
    """The first value that ``values`` holds twice (None if none)."""
    seen = set()
    return next((v for v in values if v in seen or seen.add(v)), None)
