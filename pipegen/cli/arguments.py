"""The ``pipegen`` command's argument types: each turns one option's text into its value, or
raises ``argparse.ArgumentTypeError``, which argparse reports as a usage error (exit status 2)
naming the option."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

from pipegen.core.defaults import DEFAULT_SIZE
from pipegen.compiler.inputs import param_pair

MAX_SIZE = 16384          # per side: GL_MAX_TEXTURE_SIZE of llvmpipe
DEFAULT_SIZE_TEXT = f"{DEFAULT_SIZE[0]}x{DEFAULT_SIZE[1]}"


def size_arg(text: str) -> tuple[int, int]:
    m = re.fullmatch(r"\s*(-?\d+)\s*[xX]\s*(-?\d+)\s*", text)
    if not m:
        raise argparse.ArgumentTypeError(
            f"bad size {text!r}: write WIDTHxHEIGHT, e.g. 640x360 (each side 1..{MAX_SIZE})")
    w, h = int(m.group(1)), int(m.group(2))
    if not (1 <= w <= MAX_SIZE and 1 <= h <= MAX_SIZE):
        raise argparse.ArgumentTypeError(
            f"bad size {text!r}: width and height must each be 1..{MAX_SIZE} pixels")
    return w, h


def count_arg(text: str) -> int:
    """A number of pixels allowed: a whole number, 0 or more."""
    try:
        n = int(text)
    except ValueError:
        n = -1
    if n < 0:
        raise argparse.ArgumentTypeError(f"bad count {text!r}: write a whole number, 0 or more")
    return n


def graph_path_arg(text: str) -> str:
    from pipegen.views.graph import SUFFIXES
    if Path(text).suffix.lower() not in SUFFIXES:
        raise argparse.ArgumentTypeError(
            f"bad graph file {text!r}: name it with one of {', '.join(SUFFIXES)}, "
            f"e.g. -o graph.svg")
    return text


def param_arg(text: str) -> tuple[str, object]:
    try:
        return param_pair(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def dump_after_arg(text: str) -> frozenset | str:
    """``--dump-after``: ``all`` or pass names (comma-separated), each one a compile may run."""
    from pipegen.passes.pipelines import all_pass_names
    if text.strip() == "all":
        return "all"
    names = frozenset(n.strip() for n in text.split(",") if n.strip())
    unknown = sorted(names - set(all_pass_names()))
    if unknown or not names:
        raise argparse.ArgumentTypeError(
            f"unknown pass {', '.join(map(repr, unknown)) or repr(text)}: the passes are "
            f"{', '.join(all_pass_names())} (or all)")
    return names


def join_negative_sizes(argv: list[str]) -> list[str]:
    """``--size -5x10``: argparse would take ``-5x10`` for an option; pass it as the value so
    the size check can say what is wrong with it."""
    out: list[str] = []
    i = 0
    while i < len(argv):
        if argv[i] == "--size" and i + 1 < len(argv) and re.match(r"-\d", argv[i + 1]):
            out.append("--size=" + argv[i + 1])
            i += 2
            continue
        out.append(argv[i])
        i += 1
    return out
