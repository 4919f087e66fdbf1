"""The shipped scenes (the *.toml files beside this module) and loading any scene: by name, from a
TOML file, or from an SSP package (featherstar.cosim.ssp.read)."""
from __future__ import annotations

import tomllib
from importlib import resources
from pathlib import Path

from ..errors import SceneError
from ..scene.data import Scene, scene_from_dict
from ..ssp.read import is_ssp, read_ssp


def shipped_scenes() -> dict[str, Path]:
    """The shipped scene files by name."""
    folder = resources.files(__name__)
    return {Path(str(p)).stem: Path(str(p)) for p in folder.iterdir() if str(p).endswith(".toml")}


#: Largest scene file read: a scene is a page of settings, not a data set.
MAX_SCENE_BYTES = 1 << 20


def read_scene_file(path: Path) -> dict:
    """A scene file's TOML as a dict, or a SceneError naming the file: unreadable, too large,
    not UTF-8 text (with the first bad byte's offset), not TOML."""
    try:
        with open(path, "rb") as fh:
            raw = fh.read(MAX_SCENE_BYTES + 1)
    except OSError as exc:
        raise SceneError(f"{path}: cannot read the scene file ({exc.strerror or exc})") from None
    if len(raw) > MAX_SCENE_BYTES:
        raise SceneError(f"{path}: larger than {MAX_SCENE_BYTES >> 20} MiB: not a scene file")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SceneError(f"{path}: not UTF-8 text (byte 0x{raw[exc.start]:02x} at offset {exc.start}); "
                         "TOML scene files are UTF-8") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{path}: not valid TOML: {exc}") from None


def scene_file_label(source: str | Path) -> str:
    """How a refusal names a scene's file: a shipped one by its file name, any other by its path."""
    path = Path(source)
    return path.name if path in shipped_scenes().values() else str(source)


def name_file(exc: SceneError, source: str | Path) -> SceneError:
    """The refusal with the scene's file named once, before its first problem."""
    label = scene_file_label(source)
    if not source or any(label in p for p in exc.problems):
        return exc
    return SceneError([f"{label}: {exc.problems[0]}", *exc.problems[1:]], exc.scene)


def list_scenes() -> list[tuple[str, str]]:
    """(name, one-line description) of every shipped scene."""
    out = []
    for name, path in sorted(shipped_scenes().items()):
        out.append((name, str(read_scene_file(path).get("description", "")).strip().splitlines()[0]))
    return out


def load_scene(name_or_path: str | Path | Scene, *, allow_code: bool = False) -> Scene:
    """A shipped scene by name ("testbed", "robot", "kinematic"), a TOML file by path, or an
    SSP 1.0 package (.ssp, see featherstar.cosim.ssp.read; a package naming Python code other than
    featherstar's own blocks is refused unless `allow_code`). A TOML file is the user's own and may
    name Python code."""
    if isinstance(name_or_path, Scene):
        return name_or_path
    if is_ssp(name_or_path):
        data, overrides = read_ssp(name_or_path, allow_code=allow_code)
        path = Path(name_or_path)
        return scene_from_dict(data, name=path.stem, source=str(path)).with_overrides(overrides)
    shipped = shipped_scenes()
    text = str(name_or_path)
    if text in shipped:
        path = shipped[text]
    else:
        path = Path(text)
        if not path.is_file():
            raise SceneError(
                f"no scene '{text}': not a shipped scene ({', '.join(sorted(shipped))}) and no such file"
            )
    data = read_scene_file(path)
    try:
        return scene_from_dict(data, name=path.stem, source=str(path))
    except SceneError as exc:
        raise name_file(exc, path) from None
