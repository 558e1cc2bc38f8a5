"""pedmesh._kernel_cache: a compiled module's cached machine code is deleted when a module
it takes compiled code or constants from changes, and only then."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from pedmesh import _kernel_cache as K

FILES = {
    "__init__.py": "",
    "a.py": "import numba\nX = 1\n\n@numba.njit(cache=True)\ndef f():\n    return X\n",
    "b.py": "import numba\nfrom .a import f\n",  # calls a's compiled code
    "c.py": "from .a import X\n",  # not compiled: has no cache
    "d.py": "import numba\nfrom .e import CONST\n",  # a constant of a plain module
    "e.py": "CONST = 2\n\ndef helper():\n    return 1\n",
    "g.py": "import numba\nfrom .e import helper\n",  # a plain function: not in a kernel
    "sub/__init__.py": "",
    "sub/h.py": "from numba import njit\nfrom ..a import f\n",
    "ab.py": "import numba\n",  # a file name that starts like another's
    "k.py": "import numba\nfrom . import consts as C\n",  # read as C.LIMIT in a kernel
    "consts.py": "LIMIT = 3\n",
    "m.py": "import numba\nimport pkg.consts as C\n",  # the same, imported absolutely
}
CACHED = ("a", "b", "d", "g", "ab", "sub/h", "k", "m")


def _make(root: Path) -> None:
    for rel, text in FILES.items():
        p = root / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)


def _cache(root: Path) -> None:
    """Fake numba cache files (index and data) of every compiled module."""
    for rel in CACHED:
        d = (root / rel).parent / "__pycache__"
        d.mkdir(exist_ok=True)
        stem = Path(rel).name
        (d / f"{stem}.f-4.py311.nbi").write_text("i")
        (d / f"{stem}.f-4.py311.1.nbc").write_text("c")
        (d / f"{stem}.cpython-311.pyc").write_text("p")  # never touched


def _cached(root: Path) -> set[str]:
    out = set()
    for rel in CACHED:
        d = (root / rel).parent / "__pycache__"
        stem = Path(rel).name
        if (d / f"{stem}.f-4.py311.nbi").exists():
            assert (d / f"{stem}.f-4.py311.1.nbc").exists()
            out.add(rel)
        assert (d / f"{stem}.cpython-311.pyc").exists()
    return out


def _touch(root: Path, rel: str, extra: str = "\n# changed\n") -> None:
    p = root / rel
    st = p.stat()
    p.write_text(p.read_text() + extra)
    os.utime(p, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))


@pytest.fixture
def pkg(tmp_path):
    root = tmp_path / "pkg"
    _make(root)
    _cache(root)
    assert set(K.check(root)) == {f"{r}.py" for r in CACHED}  # no record: all dropped
    _cache(root)
    return root


def test_nothing_changed_keeps_every_cache(pkg):
    assert K.check(pkg) == []
    assert _cached(pkg) == set(CACHED)
    assert (pkg / "__pycache__" / K.RECORD).is_file()


def test_a_compiled_module_changed_drops_it_and_its_users(pkg):
    _touch(pkg, "a.py")
    assert K.check(pkg) == ["a.py", "b.py", "sub/h.py"]
    assert _cached(pkg) == {"d", "g", "ab", "k", "m"}
    assert K.check(pkg) == []  # recorded: nothing more to do


def test_a_constant_changed_drops_the_modules_that_take_it(pkg):
    _touch(pkg, "e.py")
    assert K.check(pkg) == ["d.py"]
    assert _cached(pkg) == set(CACHED) - {"d"}


def test_a_plain_module_changed_drops_nothing(pkg):
    _touch(pkg, "c.py")
    assert K.check(pkg) == []
    assert _cached(pkg) == set(CACHED)


def test_a_new_import_is_read(pkg):
    """A module that starts taking compiled code from another depends on it from then on."""
    _touch(pkg, "g.py", "from .ab import nothing\n")
    assert K.check(pkg) == ["g.py"]
    _cache(pkg)
    _touch(pkg, "ab.py")
    assert K.check(pkg) == ["ab.py", "g.py"]


def test_a_removed_module_drops_its_users(pkg):
    (pkg / "a.py").unlink()
    dropped = K.check(pkg)
    assert "b.py" in dropped and "sub/h.py" in dropped and "d.py" not in dropped


def test_pedmesh_itself_is_recorded_and_unchanged_after_import():
    """``import pedmesh`` ran the check: the package's record matches its sources."""
    import pedmesh  # noqa: F401

    if not os.access(K.ROOT, os.W_OK):
        pytest.skip("a read-only install keeps no record")
    assert K.check() == []
    deps = K.kernel_dependencies({
        f: K._imports(f, (K.ROOT / f).read_text(encoding="utf-8"), set(K._sources(K.ROOT)))
        for f in K._sources(K.ROOT)})
    # the case that was met: kernels.py inlines forces.py
    assert "models/sfm/forces.py" in deps["models/sfm/kernels.py"]


def test_a_module_imported_as_a_module_counts(pkg):
    """``from . import consts as C`` (or ``import pkg.consts as C``) and ``C.LIMIT`` in a
    kernel: consts is a source of k (and of m)."""
    _touch(pkg, "consts.py")
    assert K.check(pkg) == ["k.py", "m.py"]


@pytest.mark.parametrize("text", ["[]", "null", "{\"version\": 1, \"files\": 3}",
                                  "{\"version\": 1, \"files\": {}, \"imports\": {\"a.py\": 1}}",
                                  "not json"])
def test_a_broken_record_counts_as_none(pkg, text):
    """Every compiled module's caches are dropped once and the record is written anew."""
    (pkg / "__pycache__" / K.RECORD).write_text(text)
    assert set(K.check(pkg)) == {f"{r}.py" for r in CACHED}
    assert K.check(pkg) == []


def test_a_cache_that_cannot_be_deleted_is_warned_about_and_recorded(pkg, monkeypatch):
    """A cache folder not ours to write: a warning names the file; the record is still
    written, so the other modules' caches are not dropped again at every import."""
    real = Path.unlink

    def unlink(self, *a, **k):
        if self.name.startswith("b."):
            raise PermissionError("read-only")
        return real(self, *a, **k)

    _touch(pkg, "a.py")
    monkeypatch.setattr(Path, "unlink", unlink)
    with pytest.warns(RuntimeWarning, match="b.f-4"):
        assert K.check(pkg) == ["a.py", "b.py", "sub/h.py"]
    monkeypatch.undo()
    _cache(pkg)
    assert K.check(pkg) == []
