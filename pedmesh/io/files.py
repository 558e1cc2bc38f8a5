"""Writing a file whole: through a temporary file of its own beside it, renamed when
complete (a reader never finds a half-written file, and a user's ``NAME.part`` is never
written over)."""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["temporary_beside"]


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
