"""The examples in the documentation work.

- Every ```pipe block in docs/*.md and README.md is a complete technique and compiles.
- Every ```pipe fragment block parses, as top-level declarations or as the statements of a
  fragment body (docs/language.md, "About the examples").
- A fenced block without either tag that looks like .pipe code fails: tag it.
- Every ```toml block of docs/scenes.md is a complete scene and loads; every ```toml fragment
  block loads as part of a minimal scene.
"""

import re
from pathlib import Path

import pytest

from pipegen.frontend import parse as syntax
from pipegen.compiler.driver import compile_source
from pipegen.core.diagnostics import PipegenError
from pipegen.scene import parse_scene

ROOT = Path(__file__).resolve().parent.parent
DOCS = sorted((ROOT / "docs").glob("*.md")) + [ROOT / "README.md"]
FENCE = re.compile(r"^```([^\n`]*)\n(.*?)^```\s*$", re.M | re.S)
# Lines only .pipe code has: a declaration with its punctuation, at the start of a line.
PIPE_START = re.compile(r'^\s*(technique\s+\w+\s+"|include\s+"|target\s+\w+\s*:\s*\w+|'
                        r"pass\s+\w+\s*\{|param\s+\w+\s*(:\s*\w+\s*)?=|pack\s+\w+\s*=\s*\w+\(|"
                        r"lights\s*\[\s*\w+\s*\]\s*\{)", re.M)


def _blocks():
    for path in DOCS:
        text = path.read_text()
        for m in FENCE.finditer(text):
            line = text.count("\n", 0, m.start()) + 1
            yield path, line, m.group(1).strip(), m.group(2)


def _ids(blocks):
    return [f"{p.relative_to(ROOT)}:{line}" for p, line, _, _ in blocks]


PIPE = [b for b in _blocks() if b[2] == "pipe"]
FRAGMENTS = [b for b in _blocks() if b[2] == "pipe fragment"]
UNTAGGED = [b for b in _blocks() if b[2] in ("", "text")]
TOML = [b for b in _blocks() if b[2] in ("toml", "toml fragment")]


def test_the_docs_have_examples():
    assert len([b for b in PIPE if b[0].name == "language.md"]) >= 2
    assert len(FRAGMENTS) >= 4
    assert len([b for b in TOML if b[0].name == "scenes.md"]) >= 4


@pytest.mark.parametrize("path, line, tag, code", PIPE, ids=_ids(PIPE))
def test_pipe_example_compiles(path, line, tag, code):
    # Compiled as if it sat beside the shipped techniques, so `include "common/…"` resolves
    # the way it does for them.
    compiled = compile_source(code, str(ROOT / "pipelines" / f"doc_{path.stem}_{line}.pipe"))
    assert compiled.technique.passes


@pytest.mark.parametrize("path, line, tag, code", FRAGMENTS, ids=_ids(FRAGMENTS))
def test_pipe_fragment_parses(path, line, tag, code):
    wrappers = ('technique t "t"\n{}\n',
                'technique t "t"\npass p {{\n  draw scene\n  fragment {{\n{}\n  }}\n}}\n')
    errors = []
    for w in wrappers:
        try:
            syntax.parse(w.format(code), f"{path.name}:{line}")
            return
        except PipegenError as e:
            errors.append(str(e))
    pytest.fail(f"{path.name}:{line}: the fragment parses neither as declarations nor as "
                f"statements:\n" + "\n".join(errors))


@pytest.mark.parametrize("path, line, tag, code", UNTAGGED, ids=_ids(UNTAGGED))
def test_pipe_code_is_tagged(path, line, tag, code):
    assert not PIPE_START.search(code), (
        f"{path.name}:{line}: a ```{tag} block that looks like .pipe code: tag it ```pipe "
        "(compiled) or ```pipe fragment")


_BASE_TOP = "width = 64\nheight = 36\n"
_BASE_CAMERA = "\n[camera]\nposition = [0, 4, 8]\ntarget = [0, 0, 0]\nfov_y_deg = 45\n"
_BASE_OBJECT = "\n[[objects]]\nmesh = \"plane\"\nmaterial = { albedo = [0.5, 0.5, 0.5] }\n"


@pytest.mark.parametrize("path, line, tag, code", TOML, ids=_ids(TOML))
def test_toml_example_loads(path, line, tag, code):
    if tag == "toml":
        text = code
    else:
        text = _BASE_TOP + code
        if not re.search(r"^\s*\[camera\]", code, re.M):
            text += _BASE_CAMERA
        text += _BASE_OBJECT
    scene = parse_scene(text, f"{path.name}:{line}", base_dir=path.parent)
    assert scene.objects and scene.width > 0


def test_scene_docs_list_every_key_the_loader_accepts():
    """docs/scenes.md has a table row for every key pipegen/scene/load.py checks for."""
    import inspect

    from pipegen.scene import load as scene_mod
    text = (ROOT / "docs/scenes.md").read_text()
    documented = set(re.findall(r"^\| `([a-z_]+)` \|", text, re.M))
    source = inspect.getsource(scene_mod)
    accepted = set()
    for keys in re.findall(r"check_keys\(\{([^}]*)\}", source) + \
            re.findall(r'"(?:point|spot|directional)": \{([^}]*)\}', source):
        accepted |= set(re.findall(r'"([a-z_]+)"', keys))
    assert accepted, "no check_keys calls found in pipegen/scene/load.py"
    assert accepted <= documented | {"camera", "objects", "lights"}, \
        sorted(accepted - documented)


def _anchors(markdown: str) -> set[str]:
    """GitHub's heading anchors: lower case, punctuation dropped, spaces to hyphens."""
    out = set()
    for title in re.findall(r"^#+\s+(.*?)\s*$", markdown, re.M):
        out.add(re.sub(r"\s", "-", re.sub(r"[^\w\s-]", "", title.lower())))
    return out


def test_relative_links_in_the_docs_resolve():
    bad = []
    for path in DOCS:
        text = FENCE.sub("", path.read_text())
        for target in re.findall(r"\]\(([^)\s]+)\)", text):
            if re.match(r"[a-z]+:", target):
                continue
            file, _, anchor = target.partition("#")
            dest = (path.parent / file).resolve() if file else path
            if not dest.exists():
                bad.append(f"{path.name}: {target} (no such file)")
            elif anchor and dest.suffix == ".md" and anchor not in _anchors(dest.read_text()):
                bad.append(f"{path.name}: {target} (no such heading)")
    assert not bad, bad
