"""Grammar-aware fuzzing of the front end: mutants of the shipped techniques either compile or
raise a ``PipegenError`` located inside the file (a line and column that exist in its text),
within a time bound; never a traceback, a hang or an unbounded read.

Mutations (one to three per input, chosen by a seeded RNG): token deletion, duplication and
swaps; identifiers and numbers replaced (with extremes among them); formats, blend factors,
stencil ops, compare functions… swapped for others; truncation; deep nesting (unary
operators, parentheses, braces, operator chains, if statements); odd characters (NUL, vertical
tab, form feed, U+2028, BOM, escape sequences…); odd include paths; hundreds of passes;
invalid UTF-8 bytes (those inputs go through a file and ``compile_file``).

    PIPEGEN_FUZZ=10000 pytest tests/test_fuzz_frontend.py -s     # more inputs (default 150: CI's budget)
    PIPEGEN_FUZZ_SEED=…                                          # another seed (default 8)
    PIPEGEN_FUZZ_EMIT=1                                          # also emit GLSL and OpenCL

Every input is reproducible alone from (seed, index); a failure lists them.
"""

from __future__ import annotations

import contextlib
import os
import random
import re
import signal
import time
from pathlib import Path

import pytest

from pipegen.compiler.driver import compile_file, compile_source
from pipegen.core.diagnostics import PipegenError

ROOT = Path(__file__).resolve().parents[1]
TECHNIQUES = sorted((ROOT / "pipelines").glob("*.pipe"))
COUNT = int(os.environ.get("PIPEGEN_FUZZ", "150"))
SEED = int(os.environ.get("PIPEGEN_FUZZ_SEED", "8"))
EMIT = os.environ.get("PIPEGEN_FUZZ_EMIT", "") not in ("", "0")
TIME_LIMIT = float(os.environ.get("PIPEGEN_FUZZ_TIME_LIMIT", "10"))  # seconds per input

_TOKEN = re.compile(r'''//[^\n]*|/\*.*?\*/|"(?:[^"\\\n]|\\.)*"
    |0[xX][0-9a-fA-F]+[uU]?|(?:\d+\.\d*|\.\d+|\d+)(?:[eE][+-]?\d+)?[uU]?
    |[A-Za-z_]\w*|\+\+|\+=|-=|\*=|/=|==|!=|<=|>=|&&|\|\||<<|>>|\s+|.''', re.S | re.X)

WORDS = {
    "format": "r8 rg8 rgba8 r16 rg16 rgba16 r16f rg16f rgba16f r32f rg32f rgba32f r32ui "
              "rgba8ui rgb10a2 d24s8 d32f".split(),
    "compare": "never less equal lequal greater notequal gequal always".split(),
    "stencil_op": "keep zero replace incr decr incr_wrap decr_wrap invert".split(),
    "blend_op": "add sub revsub min max".split(),
    "factor": "zero one src_color one_minus_src_color dst_color one_minus_dst_color src_alpha "
              "one_minus_src_alpha dst_alpha one_minus_dst_alpha constant_color "
              "one_minus_constant_color constant_alpha one_minus_constant_alpha "
              "src_alpha_saturate".split(),
    "volume": "sphere cone quad".split(),
    "light_type": "point spot directional".split(),
    "cull": "back front none auto".split(),
    "scheme": "bitplanes max_pairs channel_slots split16 bitfield kircher spheremap "
              "octahedral".split(),
    "type": "float int uint bool vec2 vec3 vec4 ivec2 ivec3 ivec4 uvec2 uvec3 uvec4 bvec2 "
            "bvec3 bvec4 mat3 mat4 void".split(),
    "keyword": "technique include param lights target output pack pass repeat per light draw "
               "writes reads depth stencil blend mask cull offset clear fragment scene "
               "fullscreen as in scissor write nowrite clamp inside off func ref read fail "
               "zfail zpass rgb alpha constant size samples x if else for return break "
               "continue discard true false".split(),
}
WORD_CLASS = {w: k for k, ws in WORDS.items() for w in ws if k != "keyword"}
EXTREME_NAMES = ["_", "x" * 300, "light", "lights", "color", "main", "gl_FragCoord", "void",
                 "texture", "load", "sample", "size", "num_lights", "normal", "é"]
EXTREME_NUMBERS = ["0", "-0", "0.0", "-1", "1e309", "-1e309", "3.4e38", "3.5e38", "1e-400",
                   "2147483647", "2147483648", "4294967295u", "4294967296u", "0xFFFFFFFF",
                   "0x100000000", "9" * 30, "1" + "0" * 5000, "255", "256", "65536", "1u",
                   "0u", "1.5u", "16.0", "17", "1e38", "0x7fffffff", ".5", "5."]
ODD = ["\x00", "\v", "\f", "\u2028", "\u2029", "\x85", "\r", "\r\n", "\t", "\ufeff", "é",
       "\U0001F600", "\x1b[31m", "\\", '"', "/*", "*/", "//", "\x7f", "\u200b", "$", "@", "`"]
INCLUDES = ["\\x00", "../../../../../../../../dev/zero", "/dev/null", "", ".", "common",
            "/proc/self/status", "nope.pipe", "common/../common/lighting.pipe",
            "common/light_buffer.pipe", "../pipelines/forward.pipe", "x" * 5000, "/",
            "../../../../../../../../etc/passwd"]
DEPTHS = [10, 60, 99, 100, 101, 150, 1000, 5000]
BAD_BYTES = [b"\xff", b"\xc3", b"\xed\xa0\x80", b"\xe2\x82", b"\xf8\x88\x80\x80\x80", b"\x80"]


def tokens(text: str) -> list[str]:
    return _TOKEN.findall(text)


def _significant(toks: list[str]) -> list[int]:
    return [i for i, t in enumerate(toks) if not t.isspace() and not t.startswith(("//", "/*"))]


def _pick(rng: random.Random, toks: list[str], test) -> int | None:
    idx = [i for i in _significant(toks) if test(toks[i])]
    return rng.choice(idx) if idx else None


def _is_name(t: str) -> bool:
    return bool(re.fullmatch(r"[A-Za-z_]\w*", t))


def _is_number(t: str) -> bool:
    return t[:1].isdigit() or (t[:1] == "." and t[1:2].isdigit())


def mutate(rng: random.Random, text: str) -> tuple[str, list[str], bytes | None]:
    """A mutant of ``text``: (text, what was done, bytes if the mutant is not valid UTF-8)."""
    done: list[str] = []
    raw = None
    for _ in range(rng.choice((1, 1, 1, 2, 2, 3))):
        toks = tokens(text)
        sig = _significant(toks)
        op = rng.choice(["delete", "duplicate", "swap", "swap_near", "name", "name", "number",
                         "number", "word", "word", "truncate", "nest", "odd", "include",
                         "replicate", "passes", "bytes"])
        if op == "delete" and sig:
            i = rng.choice(sig)
            done.append(f"delete {toks[i]!r}")
            del toks[i]
        elif op == "duplicate" and sig:
            i = rng.choice(sig)
            done.append(f"duplicate {toks[i]!r}")
            toks.insert(i, toks[i])
        elif op in ("swap", "swap_near") and len(sig) > 1:
            k = rng.randrange(len(sig) - 1)
            a, b = (sig[k], sig[k + 1]) if op == "swap_near" else rng.sample(sig, 2)
            done.append(f"swap {toks[a]!r} {toks[b]!r}")
            toks[a], toks[b] = toks[b], toks[a]
        elif op == "name":
            i = _pick(rng, toks, _is_name)
            if i is not None:
                pool = sorted({t for t in toks if _is_name(t)}) + WORDS["keyword"] + EXTREME_NAMES
                new = rng.choice(pool)
                done.append(f"name {toks[i]!r} -> {new!r}")
                toks[i] = new
        elif op == "number":
            i = _pick(rng, toks, _is_number)
            if i is not None:
                new = rng.choice(EXTREME_NUMBERS)
                done.append(f"number {toks[i]!r} -> {new[:20]!r}")
                toks[i] = new
        elif op == "word":
            i = _pick(rng, toks, lambda t: t in WORD_CLASS)
            if i is not None:
                same = WORDS[WORD_CLASS[toks[i]]]
                new = rng.choice(same if rng.random() < 0.8 else list(WORD_CLASS))
                done.append(f"word {toks[i]!r} -> {new!r}")
                toks[i] = new
        elif op == "truncate":
            cut = rng.randrange(len(text) + 1)
            done.append(f"truncate at {cut}")
            text = text[:cut]
            continue
        elif op == "nest":
            i = _pick(rng, toks, lambda t: _is_number(t) or _is_name(t))
            if i is not None:
                n, t = rng.choice(DEPTHS), toks[i]
                kind, new = rng.choice([
                    ("unary -", "-" * n + t), ("unary !", "!" * n + t),
                    ("parens", "(" * n + t + ")" * n), ("open parens", "(" * n + t),
                    ("braces", "{" * n + t), ("chain", "+".join([t] * n)),
                    ("minus pairs", "- " * n + t), ("calls", "f(" * n + t + ")" * n),
                    ("ifs", "if (true) " * n + t), ("fields", t + ".x" * n),
                    ("index", t + "[0]" * n), ("ternary", "true ? " * n + t + " : 0.0" * n)])
                done.append(f"nest {kind} x{n} at {t!r}")
                toks[i] = new
        elif op == "odd":
            pos = rng.randrange(len(text) + 1)
            c = rng.choice(ODD)
            done.append(f"insert {c!r} at {pos}")
            text = text[:pos] + c + text[pos:]
            continue
        elif op == "include":
            i = _pick(rng, toks, lambda t: t.startswith('"') and t.endswith(".pipe\""))
            if i is not None:
                new = rng.choice(INCLUDES)
                done.append(f"include -> {new[:40]!r}")
                toks[i] = f'"{new}"'
        elif op == "replicate" and sig:
            a = rng.choice(sig)
            b = min(len(toks), a + rng.randrange(1, 40))
            n = rng.choice((2, 10, 100, 500))
            done.append(f"replicate tokens {a}:{b} x{n}")
            toks[b:b] = toks[a:b] * n
        elif op == "passes":
            n = rng.choice((50, 300, 1000))
            done.append(f"{n} extra passes")
            toks.append("".join(f"\npass extra{k} {{ draw fullscreen writes color "
                                f"fragment {{ color = vec4(float({k}) * 0.001); }} }}"
                                for k in range(n)))
        elif op == "bytes":
            data = text.encode()
            pos = rng.randrange(len(data) + 1)
            bad = rng.choice(BAD_BYTES)
            done.append(f"bytes {bad!r} at {pos}")
            raw = data[:pos] + bad + data[pos:]
            return text, done, raw
        text = "".join(toks)
    return text, done, raw


class _TimeLimit(Exception):
    pass


@contextlib.contextmanager
def time_limit(seconds: float):
    """Interrupt a hang (SIGALRM where there is one; elsewhere only the time is checked)."""
    if not hasattr(signal, "setitimer"):
        yield
        return

    def alarm(signum, frame):
        raise _TimeLimit(f"over {seconds} s")

    old = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def position_problem(err: PipegenError, filename: str) -> str | None:
    """Why ``err`` is not located inside a file the input consists of (None if it is)."""
    s = err.span
    if s is None:
        return "no position"
    if s.file != filename and not os.path.isfile(s.file):
        return f"position in {s.file!r}, not in a source file"
    lines = s.text.split("\n")
    if not 1 <= s.line <= len(lines):
        return f"line {s.line} of {len(lines)}"
    line = lines[s.line - 1]
    if not 1 <= s.column <= len(line) + 1:
        return f"column {s.column} on a line of {len(line)} characters"
    return None


def run_one(index: int, tmp: Path) -> tuple[str, str]:
    """("compiled" | "error" | "crash", detail) for input ``index``."""
    rng = random.Random(f"{SEED}-{index}")
    original = rng.choice(TECHNIQUES)
    text, done, raw = mutate(rng, original.read_text())
    where = f"input {index} (seed {SEED}): {original.name}: {'; '.join(done)}"
    filename = str(original)
    t0 = time.perf_counter()
    try:
        with time_limit(TIME_LIMIT):
            if raw is not None:
                path = tmp / original.name
                path.write_bytes(raw)
                filename = str(path)
                compiled = compile_file(path)
            else:
                compiled = compile_source(text, filename)
            if EMIT:
                compiled.plan("gl")
                compiled.plan("cl")
    except PipegenError as e:
        problem = position_problem(e, filename)
        try:
            e.render()
        except Exception as r:       # noqa: BLE001 - a crash of the renderer is the finding
            problem = f"render() raised {r!r}"
        if problem:
            return "crash", f"{where}: {problem}: {e.message}"
        result = "error", e.message
    except BaseException as e:     # noqa: BLE001 - anything else is a crash
        if isinstance(e, KeyboardInterrupt):
            raise
        return "crash", f"{where}: {type(e).__name__}: {str(e)[:200]}"
    else:
        result = "compiled", ""
    elapsed = time.perf_counter() - t0
    if elapsed > TIME_LIMIT:
        return "crash", f"{where}: took {elapsed:.1f} s"
    return result


def test_mutants_compile_or_fail_with_a_position(tmp_path, capsys):
    counts = {"compiled": 0, "error": 0, "crash": 0}
    crashes = []
    t0 = time.perf_counter()
    for i in range(COUNT):
        kind, detail = run_one(i, tmp_path)
        counts[kind] += 1
        if kind == "crash":
            crashes.append(detail)
    with capsys.disabled():
        print(f"\nfuzz: {COUNT} inputs (seed {SEED}): {counts['compiled']} compiled, "
              f"{counts['error']} errors, {counts['crash']} crashes "
              f"in {time.perf_counter() - t0:.1f} s")
    assert not crashes, "\n".join(crashes[:20])


@pytest.mark.parametrize("text, message", [
    ("-" * 5000 + "1.0", "nested too deeply"),
    ("+".join(["1.0"] * 3000), "nested too deeply"),
    ("1e309", "too large"),
    ("1" * 5000, "does not fit"),
])
def test_known_crashes_are_located_errors(text, message):
    source = (ROOT / "pipelines/forward.pipe").read_text().replace(
        "vec3 c = ambient * albedo;", f"vec3 c = ambient * albedo * {text};")
    with pytest.raises(PipegenError, match=message) as info:
        compile_source(source, str(ROOT / "pipelines/forward.pipe"))
    assert position_problem(info.value, str(ROOT / "pipelines/forward.pipe")) is None
    assert info.value.span.line == source[:source.index("vec3 c = ambient")].count("\n") + 1
