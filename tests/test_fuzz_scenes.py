"""Fuzzing of the scene loaders: mutants of the shipped glTF (as .gltf with a data: URI, as
.gltf with a .bin file beside it, and as a .glb written with pygltflib), OBJ/MTL and TOML
scenes either load or raise a ``PipegenError`` with a location (a line and column inside
the file, or for a glTF file a byte offset, line and column, or JSON path in its message),
each within a time limit and, together, a memory limit; never a traceback, a hang or an
unbounded allocation (``pipegen/scene/limits.py``).

Mutations (one to three per input, seeded): JSON-aware value swaps (numbers to huge,
negative, fractional or 10^5000; indices out of range; uris to ``../..`` paths,
``/dev/zero``, a FIFO, a folder, bad ``data:`` URIs), deleted and duplicated keys and items,
deep nesting; for OBJ/MTL and TOML lines duplicated, deleted and swapped, numbers and
indices replaced with extremes (up to 10^6 digits), faces of many corners, ``mtllib``
paths leaving the folder; for every file byte flips, inserted garbage and truncation, and
for .glb lying header and chunk lengths.

    PIPEGEN_FUZZ_SCENES=5000 pytest -n 0 tests/test_fuzz_scenes.py -s   # more (default 150: CI's budget)
    PIPEGEN_FUZZ_SCENES_SEED=…                                         # another seed (default 29)

The inputs run in one child process (``python tests/test_fuzz_scenes.py --worker ...``)
whose address space is limited (``RLIMIT_AS``: its size after imports plus
``MEMORY_LIMIT``): an allocation past it is a ``MemoryError``, counted as a crash.  Every
input is reproducible alone from (seed, index); a failure lists them.
"""

from __future__ import annotations

import copy
import json
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "examples/models/cornell_box"
SCENES = sorted((ROOT / "examples/scenes").glob("*.toml"))
COUNT = int(os.environ.get("PIPEGEN_FUZZ_SCENES", "150"))
SEED = int(os.environ.get("PIPEGEN_FUZZ_SCENES_SEED", "29"))
TIME_LIMIT = 10.0                   # seconds per input
MEMORY_LIMIT = 2 << 30              # bytes of address space past the worker's after imports

NUMBERS = [0, -1, 1, 2, 3, 1.5, -0.5, 255, 256, 65535, 65536, 2 ** 31, 2 ** 32 + 7,
           4194305, 10 ** 12, 10 ** 40, 1e308, -1e308, 5126, 5125, 5121, 34962]
URIS = ["../../../../etc/passwd", "/dev/zero", "../../../../../dev/zero", "fifo", "folder",
        "missing.bin", "data:,", "data:application/octet-stream;base64,!!!!",
        "data:application/octet-stream;base64,AAAA", "http://example.com/x.bin",
        "buffer.bin", "link_out.bin", "%2e%2e/%2e%2e/etc/passwd", "a\u0000b"]
STRINGS = ["", "SCALAR", "VEC2", "MAT4", "BLEND", "MASK", "orthographic", "spot", "x" * 1000]
TEXT_NUMBERS = ["0", "-1", "1e999", "-1e999", "nan", "inf", "1" + "0" * 5000, "9" * 1_000_000,
                "4294967297", "0.5", "-0", "1e-400", "2147483648", "99999999999999999999"]
DEPTHS = [10, 63, 64, 65, 200, 400, 2000]


# -- JSON (glTF) -------------------------------------------------------------------------------


def _paths(doc):
    """Every (path, value) in a JSON document, depth first (a stack: a mutant may already
    nest 2000 deep)."""
    out, stack = [], [((), doc)]
    while stack:
        path, value = stack.pop()
        out.append((path, value))
        if isinstance(value, dict):
            stack += [(path + (k,), v) for k, v in reversed(value.items())]
        elif isinstance(value, list):
            stack += [(path + (i,), v) for i, v in reversed(list(enumerate(value)))]
    return out


def _set(doc, path, value):
    node = doc
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value


def mutate_json(rng: random.Random, doc: dict) -> list[str]:
    """Mutates ``doc`` in place; what was done."""
    done = []
    for _ in range(rng.choice((1, 1, 2, 3))):
        entries = [(p, v) for p, v in _paths(doc) if p]
        path, value = rng.choice(entries)
        op = rng.choice(["number", "number", "number", "uri", "string", "delete", "duplicate",
                         "swap", "nest", "type"])
        if op == "number" or (op == "uri" and not any(p == "uri" for p, _ in entries)):
            numbers = [(p, v) for p, v in entries if isinstance(v, (int, float))
                       and not isinstance(v, bool)]
            path, _ = rng.choice(numbers)
            new = rng.choice(NUMBERS)
            _set(doc, path, new)
            done.append(f"{path} = {new}")
        elif op == "uri":
            uris = [(p, v) for p, v in entries if p[-1] == "uri"]
            path, _ = rng.choice(uris)
            new = rng.choice(URIS)
            _set(doc, path, new)
            done.append(f"{path} = {new!r}")
        elif op == "string":
            strings = [(p, v) for p, v in entries if isinstance(v, str)]
            path, _ = rng.choice(strings)
            new = rng.choice(STRINGS)
            _set(doc, path, new)
            done.append(f"{path} = {new[:20]!r}")
        elif op == "delete":
            parent = doc
            for k in path[:-1]:
                parent = parent[k]
            del parent[path[-1]]
            done.append(f"delete {path}")
        elif op == "duplicate" and isinstance(value, list) and value:
            value.append(copy.deepcopy(rng.choice(value)))
            done.append(f"duplicate an item of {path}")
        elif op == "swap":
            other, other_value = rng.choice(entries)
            if other[:len(path)] != path and path[:len(other)] != other:
                _set(doc, path, copy.deepcopy(other_value))
                done.append(f"{path} = value of {other}")
        elif op == "nest":
            n = rng.choice(DEPTHS)
            _set(doc, path, f"@@nest{n}@@")        # json.dumps would recurse: see _dumps
            done.append(f"{path} nested {n} deep")
        elif op == "type":
            new = rng.choice([None, True, "7", [1, 2], {"a": 1}, 7.0])
            _set(doc, path, new)
            done.append(f"{path} = {new!r}")
    return done


def _dumps(doc: dict) -> str:
    """The JSON text of a mutant, its nesting placeholders written out as arrays."""
    return re.sub(r'"@@nest(\d+)@@"', lambda m: "[" * int(m.group(1)) + "0" + "]" * int(m.group(1)),
                  json.dumps(doc))


# -- bytes and lines ---------------------------------------------------------------------------


def mutate_bytes(rng: random.Random, data: bytes) -> tuple[bytes, str]:
    op = rng.choice(["flip", "truncate", "garbage", "zero"])
    pos = rng.randrange(len(data) + 1)
    if op == "flip" and data:
        pos = min(pos, len(data) - 1)
        return data[:pos] + bytes([data[pos] ^ (1 << rng.randrange(8))]) + data[pos + 1:], f"flip at {pos}"
    if op == "truncate":
        return data[:pos], f"truncate at {pos}"
    if op == "garbage":
        junk = bytes(rng.randrange(256) for _ in range(rng.choice((1, 16, 4096))))
        return data[:pos] + junk + data[pos:], f"{len(junk)} random bytes at {pos}"
    return data[:pos] + b"\0" * 64 + data[pos:], f"64 NULs at {pos}"


def mutate_glb(rng: random.Random, data: bytes) -> tuple[bytes, str]:
    """A lying length (header, JSON chunk, BIN chunk) or a byte mutation."""
    import struct
    json_len = struct.unpack_from("<I", data, 12)[0]
    fields = {"header length": 8, "JSON chunk length": 12, "BIN chunk length": 20 + json_len,
              "version": 4}
    if rng.random() < 0.5:
        name, at = rng.choice(sorted(fields.items()))
        value = rng.choice([0, 1, 7, len(data), len(data) + 1, 2 ** 31, 2 ** 32 - 1,
                            json_len - 1, json_len + 4])
        return data[:at] + struct.pack("<I", value) + data[at + 4:], f"{name} = {value}"
    return mutate_bytes(rng, data)


def _replace_number(rng: random.Random, text: str) -> tuple[str, str]:
    numbers = list(re.finditer(r"(?<![\w.])-?\d+(?:\.\d+)?", text))
    if not numbers:
        return text, "no number"
    m = rng.choice(numbers)
    new = rng.choice(TEXT_NUMBERS)
    return text[:m.start()] + new + text[m.end():], f"number {m.group()!r} -> {new[:12]!r} (line {text.count(chr(10), 0, m.start()) + 1})"


def mutate_lines(rng: random.Random, text: str, kind: str) -> tuple[str, list[str]]:
    done = []
    for _ in range(rng.choice((1, 1, 2, 3))):
        lines = text.split("\n")
        op = rng.choice(["duplicate", "delete", "swap", "number", "number", "bytes", "special"])
        i = rng.randrange(len(lines))
        if op == "duplicate":
            lines.insert(i, lines[i] if rng.random() < 0.7 else "\n".join([lines[i]] * 1000))
            done.append(f"duplicate line {i + 1}")
        elif op == "delete":
            del lines[i]
            done.append(f"delete line {i + 1}")
        elif op == "swap":
            j = rng.randrange(len(lines))
            lines[i], lines[j] = lines[j], lines[i]
            done.append(f"swap lines {i + 1} {j + 1}")
        elif op == "number":
            text, what = _replace_number(rng, text)
            done.append(what)
            continue
        elif op == "bytes":
            data, what = mutate_bytes(rng, text.encode())
            text = data.decode("latin-1")       # kept as bytes when written
            done.append(what)
            continue
        elif op == "special":
            extra, what = _special(rng, kind)
            lines.insert(i, extra)
            done.append(f"{what} at line {i + 1}")
        text = "\n".join(lines)
    return text, done


def _special(rng: random.Random, kind: str) -> tuple[str, str]:
    if kind == "obj":
        return rng.choice([
            ("f " + " ".join(str(1 + k % 8) for k in range(rng.choice((1025, 100_000)))), "a face of many corners"),
            ("f 1 2 " + "9" * rng.choice((20, 5000, 1_000_000)), "a huge index"),
            ("f -100000 1 2", "a relative index out of range"),
            ("f 1/1/1 2//2 3/3", "mixed corners"),
            ("mtllib " + rng.choice(["../../../../etc/passwd", "/dev/zero", "fifo", "folder",
                                     "missing.mtl"]), "an mtllib path"),
            ("v " + " ".join(["1e999"] * 3), "an infinite vertex"),
            ("usemtl " + "x" * 5000, "a long material name"),
            ("\n".join(f"f 1 {2 + k % 3} {3 + k % 4}" for k in range(3000)), "a fan of 3000 faces"),
        ])
    n = rng.choice(DEPTHS)
    return rng.choice([
        ("ambient = " + "[" * n + "1" + "]" * n, f"an array nested {n} deep"),
        ("width = " + "{a = " * n + "1" + "}" * n, f"inline tables nested {n} deep"),
        ("width." + ".".join(["a"] * n) + " = 1", f"a dotted key {n} deep"),
        ("[objects." + ".".join(["a"] * n) + "]", f"a table header {n} deep"),
        ('file = "' + rng.choice(["/dev/zero", "../../../../etc/passwd", "folder"]) + '"', "a file"),
        ("width = 1" + "0" * 5000, "a 5001-digit integer"),
    ])


# -- one input ---------------------------------------------------------------------------------


def _prepare(case: Path) -> None:
    """A case folder: the model files, and the things mutants name (a FIFO, a folder, a
    symbolic link leaving the folder)."""
    models = case / "models" / "cornell_box"
    models.mkdir(parents=True)
    for name in ("cornell_box.obj", "cornell_box.mtl", "cornell_box.gltf"):
        shutil.copy(MODEL / name, models / name)
    (case / "scenes").mkdir()
    for folder in (models, case / "scenes"):
        os.mkfifo(folder / "fifo")
        (folder / "folder").mkdir()
        os.symlink("/etc/passwd", folder / "link_out.bin")


def _gltf_forms(case: Path) -> dict[str, Path]:
    """The glTF as it ships (data: URI), with its buffer in buffer.bin, and as a .glb."""
    import pygltflib
    models = case / "models" / "cornell_box"
    doc = json.loads((models / "cornell_box.gltf").read_text())
    g = pygltflib.GLTF2().load(str(models / "cornell_box.gltf"))
    blob = g.buffers[0].uri.partition(",")[2]
    import base64
    (models / "buffer.bin").write_bytes(base64.b64decode(blob))
    doc["buffers"][0]["uri"] = "buffer.bin"
    (models / "external.gltf").write_text(json.dumps(doc))
    g.convert_buffers(pygltflib.BufferFormat.BINARYBLOB)
    g.save_binary(str(models / "cornell_box.glb"))
    return {"gltf": models / "cornell_box.gltf", "external": models / "external.gltf",
            "glb": models / "cornell_box.glb"}


def make_input(index: int, case: Path) -> tuple[Path, str]:
    """Writes input ``index`` under ``case``: the file to load and what was done."""
    rng = random.Random(f"{SEED}-{index}")
    _prepare(case)
    kind = rng.choice(["gltf", "external", "glb", "glb", "obj", "obj", "toml", "toml"])
    models = case / "models" / "cornell_box"
    if kind in ("gltf", "external", "glb"):
        path = _gltf_forms(case)[kind]
        if kind == "glb":
            data, what = mutate_glb(rng, path.read_bytes())
            path.write_bytes(data)
            return path, f"glb: {what}"
        doc = json.loads(path.read_text())
        if rng.random() < 0.8:
            done = mutate_json(rng, doc)
            path.write_text(_dumps(doc))
        else:
            data, what = mutate_bytes(rng, json.dumps(doc).encode())
            path.write_bytes(data)
            done = [what]
        return path, f"{kind}: {'; '.join(done)}"
    if kind == "obj":
        name = rng.choice(["cornell_box.obj", "cornell_box.obj", "cornell_box.mtl"])
        text, done = mutate_lines(rng, (models / name).read_text(), "obj")
        (models / name).write_bytes(text.encode("latin-1", errors="replace")
                                    if any(ord(c) > 127 for c in text) else text.encode())
        scene = case / "scenes" / "obj.toml"
        source = (ROOT / "examples/scenes/cornell_box.toml").read_text()
        scene.write_text(source)
        return scene, f"{name}: {'; '.join(done)}"
    source = rng.choice(SCENES)
    text, done = mutate_lines(rng, source.read_text(), "toml")
    scene = case / "scenes" / source.name
    scene.write_bytes(text.encode("latin-1", errors="replace"))
    return scene, f"{source.name}: {'; '.join(done)}"


_GLTF_WHERE = re.compile(r"bad glTF file: .+?: (byte \d+|line \d+, column \d+|the document"
                         r"|[A-Za-z_]\w*(\[\d+\]|\.\w+)*): ")


def location_problem(err, path: Path) -> str | None:
    """Why ``err`` (a PipegenError) is not located (None if it is)."""
    s = err.span
    if s is not None:
        lines = s.text.split("\n")
        if not 1 <= s.line <= len(lines):
            return f"line {s.line} of {len(lines)}"
        if not 1 <= s.column <= len(lines[s.line - 1]) + 1:
            return f"column {s.column} on a line of {len(lines[s.line - 1])} characters"
        return None
    if path.suffix in (".gltf", ".glb"):
        if _GLTF_WHERE.match(err.message) or err.message.startswith("cannot read glTF file"):
            return None
    return "no position"


def run_one(index: int, work: Path) -> tuple[str, str]:
    """("loaded" | "error" | "crash", detail) for input ``index``."""
    from pipegen.core.diagnostics import PipegenError
    from pipegen.scene import load_scene
    case = work / f"case{index}"
    path, done = make_input(index, case)
    where = f"input {index} (seed {SEED}): {done[:300]}"
    t0 = time.perf_counter()
    try:
        with _time_limit(TIME_LIMIT):
            load_scene(path)
        result = "loaded", ""
    except PipegenError as e:
        problem = location_problem(e, path)
        try:
            e.render()
        except Exception as r:        # noqa: BLE001 - a crash of the renderer is the finding
            problem = f"render() raised {r!r}"
        result = ("crash", f"{where}: {problem}: {e.message[:300]}") if problem else ("error", "")
    except BaseException as e:        # noqa: BLE001 - anything else is a crash
        if isinstance(e, KeyboardInterrupt):
            raise
        result = "crash", f"{where}: {type(e).__name__}: {str(e)[:300]}"
    finally:
        shutil.rmtree(case, ignore_errors=True)
    if time.perf_counter() - t0 > TIME_LIMIT:
        return "crash", f"{where}: took {time.perf_counter() - t0:.1f} s"
    return result


class _TimeLimit(Exception):
    pass


class _time_limit:
    def __init__(self, seconds: float):
        self.seconds = seconds

    def __enter__(self):
        def alarm(signum, frame):
            raise _TimeLimit(f"over {self.seconds} s")
        self.old = signal.signal(signal.SIGALRM, alarm)
        signal.setitimer(signal.ITIMER_REAL, self.seconds)

    def __exit__(self, *exc):
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, self.old)


def _limit_memory() -> int:
    """Limit this process's address space to its size now plus MEMORY_LIMIT; the limit."""
    import resource
    size = int(Path("/proc/self/statm").read_text().split()[0]) * os.sysconf("SC_PAGE_SIZE")
    limit = size + MEMORY_LIMIT
    resource.setrlimit(resource.RLIMIT_AS, (limit, resource.getrlimit(resource.RLIMIT_AS)[1]))
    return limit


def worker(first: int, count: int, work: Path) -> None:
    """Runs inputs first..first+count-1, one JSON line each on stdout."""
    import warnings
    import numpy  # noqa: F401 - imported before the limit is measured
    import pygltflib  # noqa: F401
    import jsonschema  # noqa: F401
    from pipegen.scene import load_scene  # noqa: F401
    warnings.simplefilter("ignore")
    _limit_memory()
    for i in range(first, first + count):
        kind, detail = run_one(i, work)
        print(json.dumps({"index": i, "kind": kind, "detail": detail}), flush=True)


# -- the tests ---------------------------------------------------------------------------------


def test_scene_mutants_load_or_fail_with_a_location(tmp_path, capsys):
    if not hasattr(signal, "setitimer") or not Path("/proc/self/statm").exists():
        import pytest
        pytest.skip("needs SIGALRM and /proc (Linux)")
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, __file__, "--worker", "0", str(COUNT), str(tmp_path)],
                          capture_output=True, text=True, env=env,
                          timeout=60 + COUNT * TIME_LIMIT)
    rows = [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]
    counts = {"loaded": 0, "error": 0, "crash": 0}
    for row in rows:
        counts[row["kind"]] += 1
    crashes = [row["detail"] for row in rows if row["kind"] == "crash"]
    with capsys.disabled():
        print(f"\nscene fuzz: {len(rows)} inputs (seed {SEED}): {counts['loaded']} loaded, "
              f"{counts['error']} errors, {counts['crash']} crashes "
              f"in {time.perf_counter() - t0:.1f} s")
    assert proc.returncode == 0 and len(rows) == COUNT, (
        f"the worker stopped after {len(rows)} of {COUNT} inputs (exit {proc.returncode}):\n"
        + proc.stderr[-3000:])
    assert not crashes, "\n".join(crashes[:20])
    assert counts["loaded"] > 0 and counts["error"] > COUNT // 4     # the mutants do both


if __name__ == "__main__" and sys.argv[1:2] == ["--worker"]:
    worker(int(sys.argv[2]), int(sys.argv[3]), Path(sys.argv[4]))
