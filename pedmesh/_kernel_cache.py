"""numba's on-disk caches kept true to the sources they were compiled from.

numba (``cache=True``) keys a function's cached machine code on the time stamp and size of
the file that defines it, and of no other. pedmesh's kernels call and inline compiled
functions of other pedmesh modules (``kernels.py`` inlines ``forces.py``) and freeze their
module-level constants: when only such another module changes (a ``git pull`` into an
editable install, an edit), the kernel's cache still matches its own file and numba would
load the old machine code, the old physics, without a word.

So, on ``import pedmesh``, :func:`check` compares each compiled module's sources with those
recorded when its caches were last known to match, and deletes the cached code of every
compiled module with a changed source among them; numba compiles it anew on first use.
When nothing changed (the usual case) the check walks the package and reads the record
(``pedmesh/__pycache__/kernel_sources.json``): about 2-3 ms.

A compiled module is one that imports ``numba`` (anywhere in the file). Its sources are
its own file and, read from its ``import`` statements:

* the pedmesh modules it imports UPPER_CASE names from (constants numba may freeze) or
  imports as modules (``from . import forces``: their constants may be read as
  ``forces.X``);
* the compiled pedmesh modules it imports anything from, and their sources in turn.

Conservative where it cannot tell (an UPPER_CASE name used only in Python code counts:
any edit of ``parameters.py`` recompiles the modules that take its defaults), blind where
the imports do not say it: a lowercase module-level array or a constant passed on through
a module that does not import numba. Known limits: a process that imported a kernel module
before an edit and compiles it after another process ran the check writes the old code
under the new record (delete the caches by hand then, docs/development.md); and where the
package folder cannot be written (a read-only install, a shared checkout) the check is
skipped, and a cache folder that cannot be written is warned about and left as it is.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

__all__ = ["check", "kernel_dependencies"]

#: the package as numba names its files (``os.path.abspath``, symbolic links not followed:
#: numba's cache folders outside the tree are named after that path)
ROOT = Path(os.path.abspath(__file__)).parent
PACKAGE = ROOT.name
RECORD = "kernel_sources.json"
#: the record's layout (a record of another version is ignored, as if there were none)
VERSION = 1


def _sources(root: Path) -> dict[str, list[int]]:
    """{path relative to ``root``: [size, mtime_ns]} of every ``.py`` file under it."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = [d for d in dirnames if d != "__pycache__" and not d.startswith(".")]
        for f in filenames:
            if f.endswith(".py"):
                p = os.path.join(dirpath, f)
                try:
                    st = os.stat(p)
                except OSError:
                    continue
                out[os.path.relpath(p, root).replace(os.sep, "/")] = [st.st_size,
                                                                       st.st_mtime_ns]
    return out


def _module_file(parts: list[str], files: set[str]) -> str | None:
    """The file (relative) of the module ``parts`` below the package root, if it is one."""
    if not parts:
        return "__init__.py" if "__init__.py" in files else None
    base = "/".join(parts)
    for cand in (base + ".py", base + "/__init__.py"):
        if cand in files:
            return cand
    return None


def _imports(rel: str, text: str, files: set[str], package: str = PACKAGE
             ) -> tuple[bool, list[tuple[str, bool]]]:
    """(whether ``rel`` defines compiled code (imports ``numba``), [(imported pedmesh file,
    whether UPPER_CASE names are taken from it or it is imported as a module)]) of the
    source ``text`` of the file ``rel``."""
    import ast

    try:
        tree = ast.parse(text)
    except SyntaxError:
        return "numba" in text, []
    pkg = rel.split("/")[:-1]  # the package the file is in
    compiled = False
    out = []

    def add(parts: list[str], names) -> None:
        target = _module_file(parts, files)
        if target is not None:
            out.append((target, any(a.name.isupper() for a in names)))
        for a in names:  # ``from . import module``: its constants may be read as C.X
            sub = _module_file(parts + [a.name], files)
            if sub is not None:
                out.append((sub, True))

    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            mod = node.module.split(".") if node.module else []
            if node.level:
                up = node.level - 1
                if up <= len(pkg):
                    add(pkg[: len(pkg) - up] + mod, node.names)
            elif mod and mod[0] == "numba":
                compiled = True
            elif mod and mod[0] == package:
                add(mod[1:], node.names)
        elif isinstance(node, ast.Import):
            for a in node.names:
                parts = a.name.split(".")
                if parts[0] == "numba":
                    compiled = True
                elif parts[0] == package:  # ``import pedmesh.x as X``: X.CONST, as above
                    target = _module_file(parts[1:], files)
                    if target is not None:
                        out.append((target, True))
    return compiled, out


def kernel_dependencies(info: dict[str, tuple[bool, list[tuple[str, bool]]]]
                        ) -> dict[str, set[str]]:
    """{file: the files whose change makes its cached machine code stale} (itself
    included), from :func:`_imports` of every file: the compiled modules it imports, the
    modules it takes UPPER_CASE names from or imports as modules, and theirs, transitively
    through the compiled ones."""
    direct = {}
    for f, (_, imps) in info.items():
        direct[f] = {t for t, upper in imps if t in info and (info[t][0] or upper)}
    out = {}
    for f in info:
        seen = {f}
        stack = [f]
        while stack:
            g = stack.pop()
            for h in direct.get(g, ()):
                if h not in seen:
                    seen.add(h)
                    if info[h][0]:  # (only compiled code passes its own imports on)
                        stack.append(h)
        out[f] = seen
    return out


def _cache_dirs(path: Path) -> list[Path]:
    """The directories numba may keep ``path``'s cached code in: ``__pycache__`` beside it,
    and numba's ``NUMBA_CACHE_DIR`` or user-wide cache (its own locators' rule), those
    that exist."""
    dirs = [path.parent / "__pycache__"]
    try:  # (only on this slow path: numba is imported by the kernels anyway)
        from numba.core import config
        from numba.core.caching import _CacheLocator

        sub = _CacheLocator.get_suitable_cache_subpath(str(path))
        if config.CACHE_DIR:
            dirs.append(Path(config.CACHE_DIR) / sub)
        from numba.misc.appdirs import AppDirs

        dirs.append(Path(AppDirs(appname="numba", appauthor=False).user_cache_dir) / sub)
    except Exception:  # (another numba: the in-tree cache, numba's default, only)
        pass
    return [d for d in dirs if d.is_dir()]


def _drop_caches(root: Path, rel: str) -> int:
    """Delete the cached machine code of the module ``rel``; returns the files deleted."""
    path = root / rel
    stem = path.stem + "."
    n = 0
    for d in _cache_dirs(path):
        for f in d.iterdir():
            if f.name.startswith(stem) and f.suffix in (".nbi", ".nbc"):
                try:
                    f.unlink()
                    n += 1
                except FileNotFoundError:
                    pass
                except OSError as exc:  # (a folder not ours to write: numba's own check)
                    import warnings

                    warnings.warn(f"pedmesh: could not delete the stale compiled code {f}: "
                                  f"{exc}", RuntimeWarning, stacklevel=3)
    return n


def _valid(record) -> dict:
    """``record`` if it is a record of this layout, else {} (as if there were none)."""
    try:
        if record.get("version") != VERSION:
            return {}
        files, imports = record["files"], record["imports"]
        for k, v in files.items():
            size, mtime = v
            int(size), int(mtime), str(k)
        for k, (c, imps) in imports.items():
            for t, u in imps:
                str(t), bool(u)
        return record
    except (AttributeError, KeyError, TypeError, ValueError):
        return {}


def check(root: Path = ROOT) -> list[str]:
    """Delete the stale cached machine code under the package ``root`` (see the module
    docstring); returns the modules (relative paths) whose caches were deleted."""
    record_path = root / "__pycache__" / RECORD
    now = _sources(root)
    try:
        old = _valid(json.loads(record_path.read_text()))
    except (OSError, ValueError):
        old = {}
    old_files = old.get("files", {})
    if old_files == now:
        return []
    if not os.access(root, os.W_OK):
        return []
    changed = {f for f in set(now) | set(old_files) if now.get(f) != old_files.get(f)}
    files = set(now)
    cached_info = old.get("imports", {})
    info = {}
    for f in now:
        prev = cached_info.get(f)
        if f not in changed and prev is not None:
            info[f] = (bool(prev[0]), [(t, bool(u)) for t, u in prev[1]])
            continue
        try:
            text = (root / f).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError):
            text = ""
        info[f] = _imports(f, text, files, root.name)
    gone = {f: (bool(cached_info[f][0]), []) for f in set(old_files) - files
            if f in cached_info}  # (removed: what depended on them still does)
    deps = kernel_dependencies({**info, **gone})
    stale = sorted(f for f, d in deps.items() if f in info and info[f][0] and d & changed)
    for f in stale:
        _drop_caches(root, f)
    record = {"version": VERSION, "files": now,
              "imports": {f: [int(c), [[t, int(u)] for t, u in imps]]
                          for f, (c, imps) in info.items()}}
    try:
        record_path.parent.mkdir(exist_ok=True)
        tmp = record_path.with_name(f"{RECORD}.{os.getpid()}.tmp")
        tmp.write_text(json.dumps(record))
        os.replace(tmp, record_path)
    except OSError:
        pass
    return stale
