"""What the editor has open: the map, the folder that saves may go to, and the file's text.

A session opens a map file, a SocialGym 2.0 map folder (imported by
:func:`sgjax.maps.import_socialgym`) or a new empty map. Saves stay inside ``root``; a map saved
unchanged is written back byte for byte; an autosave beside the file keeps unsaved edits.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from sgjax.files import write_atomic
from sgjax.maps.check import MapProblem, check_map


class EditorError(Exception):
    """A request the editor refuses: ``status`` is the HTTP status, ``extra`` more JSON fields."""

    def __init__(self, status: int, message: str, **extra: Any):
        super().__init__(message)
        self.status, self.extra = status, extra


def empty_map(name: str) -> dict[str, Any]:
    """A new map: a 20 m x 12 m drawing extent and nothing in it."""
    return {"name": name, "description": "", "bounds": [-10.0, -6.0, 10.0, 6.0], "walls": [],
            "nodes": [], "edges": [], "groups": []}


def map_text(data: dict[str, Any]) -> str:
    """A map's file text, as :func:`sgjax.maps.save` writes it."""
    return json.dumps(data, indent=1) + "\n"


class EditorSession:
    """The opened map and where it may be saved.

    ``root`` (a folder): every save and autosave stays inside it; ``file``: the map's file name
    relative to ``root``; ``data``: the map JSON as opened; ``text``: the file's text (None for a
    new or imported map); ``import_report``: lines from the SocialGym importer."""

    def __init__(self, root: Path, file: str, data: dict[str, Any], text: str | None = None,
                 import_report: list[str] | None = None):
        self.root = root.resolve()
        self.file = file
        self.data = data
        self.text = text
        self.import_report = import_report or []

    @classmethod
    def open(cls, target: str | None, new: str | None = None, root: str | None = None
             ) -> EditorSession:
        """A session for ``target`` (a map .json file or a SocialGym 2.0 folder) or, with
        ``new``, a new map ``NEW.json`` in ``root`` (default: the current folder)."""
        if (target is None) == (new is None):
            raise EditorError(400, "give a map file or folder to open, or --new NAME")
        if new is not None:
            name = new[:-len(".json")] if new.endswith(".json") else new
            if not name or "/" in name or "\\" in name:
                raise EditorError(400, f"--new {new!r}: expected a plain name such as mygame")
            folder = Path(root or ".")
            if (folder / f"{name}.json").exists():
                raise EditorError(400, f"{folder / (name + '.json')} exists; open it instead "
                                       f"(sgjax edit {folder / (name + '.json')})")
            return cls(folder, f"{name}.json", empty_map(name))
        path = Path(target)
        if path.is_dir():
            from sgjax.maps.socialgym import import_socialgym

            report: list[Any] = []
            spec = import_socialgym(path, report=report.append)
            lines = [str(r) for r in report]
            return cls._in_root(path / f"{path.resolve().name}.json", root, spec.to_json(),
                                None, lines)
        if not path.is_file():
            raise EditorError(400, f"no such map file or folder: {path}")
        text = path.read_text()
        try:
            data = json.loads(text)
        except json.JSONDecodeError as err:
            raise EditorError(400, f"{path}: line {err.lineno} column {err.colno}: invalid "
                                   f"JSON: {err.msg}") from None
        if not isinstance(data, dict):
            raise EditorError(400, f"{path}: expected a JSON object (a map)")
        return cls._in_root(path, root, data, text, [])

    @classmethod
    def _in_root(cls, path: Path, root: str | None, data: dict, text: str | None,
                 report: list[str]) -> EditorSession:
        folder = Path(root).resolve() if root else path.parent.resolve()
        if not path.resolve().is_relative_to(folder):
            raise EditorError(400, f"--root {folder} does not hold {path}")
        return cls(folder, str(path.resolve().relative_to(folder)), data, text, report)

    # --- paths -----------------------------------------------------------------------------

    def resolve(self, file: str) -> Path:
        """The path of ``file`` (relative to the root): refused unless it is a ``.json`` file
        inside the root."""
        if not isinstance(file, str) or not file.endswith(".json"):
            raise EditorError(400, f"file {file!r}: expected a name ending in .json")
        path = (self.root / file).resolve()
        if not path.is_relative_to(self.root) or Path(file).is_absolute():
            raise EditorError(403, f"refused: {file!r} is outside the folder {self.root} that "
                                   "this editor saves to")
        return path

    @property
    def autosave_path(self) -> Path:
        path = self.resolve(self.file)
        return path.with_name(f".{path.name}.autosave")

    # --- requests ----------------------------------------------------------------------------

    def autosaved(self) -> dict[str, Any] | None:
        """The autosaved map, if one is there and differs from the opened one."""
        path = self.autosave_path
        if not path.is_file():
            return None
        try:
            data = json.loads(path.read_text())
        except json.JSONDecodeError:
            return None
        return None if data == self.data else data

    def autosave(self, data: dict[str, Any]) -> Path:
        path = self.autosave_path
        write_atomic(path, map_text(data))
        return path

    def check(self, data: Any) -> list[MapProblem]:
        return check_map(data, self.file)

    def save(self, data: dict[str, Any], file: str, overwrite: bool) -> tuple[Path, int]:
        """Write ``data`` to ``file``: refused outside the root, over an existing file other
        than the one being edited unless ``overwrite``, or with errors. Unchanged from what was
        opened: the opened text."""
        path = self.resolve(file)
        if path.exists() and not overwrite and path != self.resolve(self.file):
            raise EditorError(409, f"{file} exists; confirm to overwrite it", exists=True)
        errors = [p for p in self.check(data) if p.severity == "error"]
        if errors:
            raise EditorError(422, f"not saved: the map has {len(errors)} error(s), the first "
                                   f"{errors[0].path}: {errors[0].message}",
                              problems=[p.as_dict() for p in errors])
        text = self.text if self.text is not None and data == self.data else map_text(data)
        path.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(path, text)
        if self.autosave_path.is_file():
            self.autosave_path.unlink()
        self.data, self.text, self.file = data, text, str(path.relative_to(self.root))
        return path, len(text.encode())
