"""The shipped scenes (the *.toml files beside this module) and loading any scene: by name, from a
TOML file, or from an SSP package (featherstar.cosim.ssp.read)."""
from __future__ import annotations

import tomllib
from importlib import resources
from pathlib import Path

from ..errors import SceneError
from ..scene.data import Scene, scene_from_dict
from ..ssp.read import is_ssp, read_ssp


def _shipped() -> dict[str, Path]:
    folder = resources.files(__name__)
    return {Path(str(p)).stem: Path(str(p)) for p in folder.iterdir() if str(p).endswith(".toml")}


def list_scenes() -> list[tuple[str, str]]:
    """(name, one-line description) of every shipped scene."""
    out = []
    for name, path in sorted(_shipped().items()):
        with open(path, "rb") as fh:
            out.append((name, str(tomllib.load(fh).get("description", "")).strip().splitlines()[0]))
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
    shipped = _shipped()
    text = str(name_or_path)
    if text in shipped:
        path = shipped[text]
    else:
        path = Path(text)
        if not path.is_file():
            raise SceneError(
                f"no scene '{text}': not a shipped scene ({', '.join(sorted(shipped))}) and no such file"
            )
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{path}: not valid TOML: {exc}") from None
    return scene_from_dict(data, name=path.stem, source=str(path))
