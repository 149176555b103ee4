"""Scene files: TOML in (`load_scene`, `list_scenes`: the built-in scenes and files) and out (`scene_to_toml`)."""

from __future__ import annotations

import importlib.resources
import os
import tomllib
from pathlib import Path

import tomli_w

from ..errors import SceneError, one_line
from .checks import file_kind
from .limits import MAX_FILE_BYTES
from .scene import Scene

__all__ = ["list_scenes", "load_scene", "scene_to_toml"]

def _builtin_dir():
    return importlib.resources.files("stringcontact").joinpath("scenes")


def _builtin_names() -> list[str]:
    try:
        entries = list(_builtin_dir().iterdir())
    except (FileNotFoundError, NotADirectoryError, ModuleNotFoundError):
        return []
    return sorted(e.name[: -len(".toml")] for e in entries if e.name.endswith(".toml"))


def _parse_toml(raw: bytes, label: str) -> dict:
    if len(raw) > MAX_FILE_BYTES:
        raise SceneError(f"scene file {label!r}: larger than {MAX_FILE_BYTES} bytes; scene files are small text files")
    if b"\x00" in raw:
        raise SceneError(f"scene file {label!r}: binary file (contains NUL bytes); expected a UTF-8 TOML text file")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise SceneError(f"scene file {label!r}: not UTF-8 text (byte 0x{raw[exc.start]:02x} at line {line}); "
                         "expected a UTF-8 TOML file") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"scene file {label!r}: invalid TOML: {one_line(exc)}") from None
    except RecursionError:  # tomllib recurses once per level of [[[...]]]; no scene nests at all
        raise SceneError(f"scene file {label!r}: malformed TOML: arrays or tables nested too deeply") from None


def load_scene(name_or_path: str | os.PathLike) -> Scene:
    """Load a built-in scene by name (``"example1"``, looked up first) or a scene file by path."""
    try:
        text = os.fsdecode(name_or_path)
    except TypeError:
        raise SceneError(f"scene: expected a scene name or a path, got {type(name_or_path).__name__}") from None
    builtins = _builtin_names()
    # a name (str or bytes) is a built-in scene first; a Path only when no such file exists
    if text in builtins and (isinstance(name_or_path, (str, bytes)) or not Path(text).exists()):
        raw = _builtin_dir().joinpath(f"{text}.toml").read_bytes()
        return Scene.from_dict(_parse_toml(raw, text), source=text, default_name=text)

    path = Path(text)
    if not path.is_file():
        if path.is_dir():
            raise SceneError(f"scene {text!r}: is a directory; expected a .toml scene file")
        if path.exists():  # a FIFO, a device, a socket: stat only, never open (a FIFO would block)
            kind = file_kind(path.stat().st_mode)
            raise SceneError(f"scene {text!r}: is not a regular file ({kind}); expected a .toml scene file")
        raise SceneError(f"scene {text!r}: no built-in scene of that name and no such file "
                         f"(built-in scenes: {', '.join(builtins) or 'none'})")
    try:
        with open(path, "rb") as f:
            raw = f.read(MAX_FILE_BYTES + 1)  # bounded: a larger file is refused by its size
    except OSError as exc:
        raise SceneError(f"scene file {text!r}: cannot read it ({exc.strerror or exc})") from None
    data = _parse_toml(raw, text)
    if isinstance(data.get("mesh"), str) and not Path(data["mesh"]).is_absolute():
        data["mesh"] = os.path.abspath(path.parent / data["mesh"])  # next to its scene file, wherever it is shown
    return Scene.from_dict(data, source=text, default_name=path.stem)


def list_scenes() -> list[tuple[str, str]]:
    """(name, one-line description) of the built-in scenes, sorted by name."""
    result = []
    for name in _builtin_names():
        try:
            data = _parse_toml(_builtin_dir().joinpath(f"{name}.toml").read_bytes(), name)
            description = str(data.get("description", ""))
        except SceneError:
            description = "(unreadable)"
        result.append((name, (description.strip().splitlines() or [""])[0]))
    return result


def scene_to_toml(scene: Scene, penalty: bool = True) -> str:
    """The scene as a TOML scene file (loadable by :func:`~stringcontact.load_scene`), with dt, dx and (where it
    gives ε and `penalty`) r = Δt/ε in a comment."""
    r = f", r = dt/eps = {scene.r:.6g}" if penalty and scene.eps is not None else ""
    comment = f"# scene {scene.name!r}: dt = {scene.dt:.6g}, dx = {scene.dx:.6g}{r}\n"
    return comment + tomli_w.dumps(scene.as_dict(), multiline_strings=True)
