"""Writing a file whole: through a temporary file of its own beside it, renamed when
complete (a reader never finds a half-written file, and a user's ``NAME.part`` is never
written over)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Callable

__all__ = ["temporary_beside", "write_whole", "write_through_part"]


def temporary_beside(path: str | os.PathLike) -> Path:
    """A new, empty file next to ``path`` with a name of its own (``.NAME.XXXXXX.part``
    plus ``path``'s suffix), to write ``path`` into and rename: never a file of the
    user's (``NAME.part`` may be theirs)."""
    import tempfile

    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.",
                               suffix=".part" + path.suffix)
    os.close(fd)
    return Path(tmp)


def write_whole(path: str | os.PathLike, data: str | bytes) -> Path:
    """Write ``data`` (text as UTF-8, or bytes) to ``path`` through a
    :func:`temporary_beside` renamed when complete; a failed write removes its temporary
    file and raises the OSError."""
    path = Path(path)
    tmp = None
    try:
        tmp = temporary_beside(path)
        if isinstance(data, bytes):
            tmp.write_bytes(data)
        else:
            tmp.write_text(data, encoding="utf-8")
        os.replace(tmp, path)
    except OSError:
        if tmp is not None:
            tmp.unlink(missing_ok=True)
        raise
    return path


def write_through_part(path: str | os.PathLike, write: Callable[[Path], object]) -> Path:
    """``write(path.part)``, then rename it to ``path``: the file is the old one or the new
    one, never half of it; a failed write (or a Ctrl-C) removes the ``.part``. For the
    files whose temporary name is part of their folder's contract (a run folder's
    ``summary.json.part``, :data:`pedmesh.io.run_folder.TEMP_FILES`)."""
    path = Path(path)
    tmp = path.with_name(path.name + ".part")
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)  # never leave a .part behind (e.g. a full disk)
        raise
    return path
