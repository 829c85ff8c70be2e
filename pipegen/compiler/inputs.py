"""What the commands read from their arguments: a technique file (a scene file given in its
place says so) and parameter values written as text (``-p NAME=VALUE``, sweep axes).

Shared by ``cli`` and the tools it runs (``sweep``, ``stress``), which import it instead of the
command line: the command line sits above them and imports them, never the reverse.
"""

from __future__ import annotations

from pathlib import Path

from pipegen.core.diagnostics import PipegenError


def literal(text: str):
    """A parameter value written as text: an int, a float, ``true``/``false``, else the text."""
    for conv in (int, float):
        try:
            return conv(text)
        except ValueError:
            pass
    if text in ("true", "false"):
        return text == "true"
    return text


def param_pair(text: str) -> tuple[str, object]:
    """``NAME=VALUE`` -> ``(name, value)``; a ``ValueError`` saying what is wrong."""
    name, sep, value = text.partition("=")
    if not sep or not name.strip():
        raise ValueError(f"bad parameter override {text!r}: write NAME=VALUE, "
                         f"e.g. -p lbuffer_scale=0.5")
    return name.strip(), literal(value.strip())


def parse_params(items: list) -> dict:
    """``["NAME=VALUE", ...]`` (or already-parsed pairs) -> ``{name: value}``."""
    params = {}
    for item in items:
        if isinstance(item, str):
            try:
                item = param_pair(item)
            except ValueError as e:
                raise PipegenError(None, str(e)) from None
        params[item[0]] = item[1]
    return params


def compile_technique(file, params: list, watch=None):
    """Compile the technique ``file`` with ``params`` (``NAME=VALUE`` texts or pairs); a scene
    file given instead says so.  ``watch``: what to show of the passes (``manager.Watch``)."""
    from pipegen.compiler.driver import compile_file
    path = Path(file)
    if path.suffix.lower() == ".toml":
        raise scene_not_technique(path)
    try:
        return compile_file(path, parse_params(params), watch=watch)
    except PipegenError:
        if looks_like_scene(path):
            raise scene_not_technique(path) from None
        raise


def looks_like_scene(path: Path) -> bool:
    import tomllib
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return False
    return bool({"camera", "objects", "lights"} & set(data))


def scene_not_technique(path: Path) -> PipegenError:
    return PipegenError(None, f"{path}: this looks like a scene file (.toml), not a technique "
                              f"(.pipe)",
                        hint=f"the first argument is the technique; give the scene with "
                             f"--scene, e.g. pipegen run pipelines/forward.pipe --scene {path} "
                             f"-o out/forward")
