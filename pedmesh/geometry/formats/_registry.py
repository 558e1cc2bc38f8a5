"""Registry of geometry file formats, keyed by file suffix."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from ...errors import RoomFileError, UnsupportedFormatError

__all__ = ["RoomFormat", "register_format", "formats", "format_for", "read_text",
           "existing_file"]


@dataclass(frozen=True)
class RoomFormat:
    """A geometry file format: a name, its suffixes, a reader and an optional writer."""

    name: str
    suffixes: tuple[str, ...]
    reader: Callable
    writer: Callable | None = None


_FORMATS: dict[str, RoomFormat] = {}


def register_format(fmt: RoomFormat) -> None:
    """Register a format for its suffixes (lower case, with the dot)."""
    for s in fmt.suffixes:
        _FORMATS[s.lower()] = fmt


def formats() -> dict[str, RoomFormat]:
    """Suffix -> format of every registered format."""
    return dict(_FORMATS)


def format_for(path: str | Path) -> RoomFormat:
    """The format registered for ``path``'s suffix."""
    suffix = Path(path).suffix.lower()
    if suffix not in _FORMATS:
        known = ", ".join(sorted(_FORMATS))
        raise UnsupportedFormatError(
            f"{path}: unsupported geometry file suffix '{suffix or '(none)'}' (known: {known})"
        )
    return _FORMATS[suffix]


def existing_file(path: str | Path) -> Path:
    """``path`` as a Path, with clear errors if it is missing, a directory or empty."""
    p = Path(path)
    if not p.exists():
        raise RoomFileError(f"{path}: no such file")
    if p.is_dir():
        raise RoomFileError(f"{path}: is a directory, not a geometry file")
    if p.stat().st_size == 0:
        raise RoomFileError(f"{path}: the file is empty")
    return p


def read_text(path: str | Path) -> str:
    """The file's text, with clear errors for missing, unreadable or empty files."""
    p = existing_file(path)
    try:
        text = p.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise RoomFileError(f"{path}: not a UTF-8 text file") from None
    except OSError as exc:
        raise RoomFileError(f"{path}: cannot read ({exc.strerror})") from None
    if not text.strip():
        raise RoomFileError(f"{path}: the file is empty")
    return text
