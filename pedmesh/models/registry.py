"""The one model registry: every model ``pedmesh run`` (and compare, ensemble, the Python
API) can run is one :class:`ModelEntry`.

An entry says what the model is (its parameters, as declarations: :mod:`pedmesh.parameters`),
how to build it (``build(room, mesh, parameters, **options)`` returning a
:class:`~pedmesh.models.protocol.RunModel`) and what it can do (its scale, the options it
takes, whether it has random input). The driver and the workflows read entries; none of
them knows a model by name.

Adding a model is one module that defines its run object and calls :func:`register_model`
once (see ``tests/run/test_toy_model.py`` for a constant-velocity continuum model in one
file).

The built-in models register themselves when their modules are imported, and those are
imported on the registry's first use (:data:`BUILTINS`), not with :mod:`pedmesh.models`:
:func:`get_model` of a built-in model's name imports that model's module only (a run of
eos does not import the social force model, issue 46); any other name, and every other
function here, imports them all first.
"""

from __future__ import annotations

import importlib
import threading
from dataclasses import dataclass
from typing import Any, Callable, Iterable

from ..errors import ParameterError
from ..parameters import Parameter

__all__ = ["ModelEntry", "register_model", "unregister_model", "get_model", "model_names",
           "entries", "PARTICLES", "CONTINUUM"]

#: the two scales: a model of individual pedestrians, or of densities on the mesh
PARTICLES = "particles"
CONTINUUM = "continuum"


@dataclass(frozen=True)
class ModelEntry:
    """One registered model.

    * ``name``: the canonical name (``--model NAME``); ``aliases``: other names for it.
    * ``build(room, mesh, parameters, **options)``: the run object
      (:class:`~pedmesh.models.protocol.RunModel`); ``parameters`` holds the preset's values
      and the user's overrides by name, ``options`` the model options below.
    * ``parameters``: every parameter the model takes (physics and numerics), declared
      once each (:class:`~pedmesh.parameters.Parameter`). A preset sets those of them it
      has values for.
    * ``scale``: ``"particles"`` or ``"continuum"``: a continuum model takes a preset's
      continuum values (:attr:`pedmesh.presets.Preset.continuum`) over its others.
    * ``options``: the model options ``build`` accepts besides the parameters (e.g.
      ``seed``, ``static_routes``, ``trajectory_rate``, ``positions``, ``rho0``).
    * ``random``: the model has random input (a seed), so an ensemble's members differ.
    * ``description``: one line for listings.
    """

    name: str
    build: Callable[..., Any]
    parameters: tuple[Parameter, ...] = ()
    scale: str = CONTINUUM
    options: frozenset[str] = frozenset()
    random: bool = False
    aliases: tuple[str, ...] = ()
    description: str = ""

    def __post_init__(self) -> None:
        if self.scale not in (PARTICLES, CONTINUUM):
            raise ValueError(f"model scale must be '{PARTICLES}' or '{CONTINUUM}', "
                             f"got {self.scale!r}")
        object.__setattr__(self, "options", frozenset(self.options))
        object.__setattr__(self, "parameters", tuple(self.parameters))

    @property
    def parameter_names(self) -> frozenset[str]:
        """The names of :attr:`parameters`."""
        return frozenset(p.name for p in self.parameters)


_ENTRIES: dict[str, ModelEntry] = {}
_ALIASES: dict[str, str] = {}

#: the modules of the built-in models, each with the canonical names it registers that
#: :func:`get_model` may look up by importing that module alone (an alias or another name
#: imports them all)
BUILTINS: dict[str, tuple[str, ...]] = {
    "pedmesh.models.sfm": ("sfm",),
    "pedmesh.models.continuum.eos": ("eos",),
    "pedmesh.models.continuum.rdue": ("rdue",),
    "pedmesh.models.continuum.pw": ("pw",),
    "pedmesh.models.continuum.derived": (),
}
#: (per thread: how deep in :func:`_load_builtins` its imports are)
_LOADING = threading.local()


def _load_builtins(modules: Iterable[str] = BUILTINS) -> None:
    """Import the built-in models' ``modules`` (each registers its models when first
    imported; Python's import lock makes another thread wait for a module being imported)."""
    _LOADING.depth = getattr(_LOADING, "depth", 0) + 1
    try:
        for name in modules:
            importlib.import_module(name)
    finally:
        _LOADING.depth -= 1


def register_model(entry: ModelEntry, *, replace: bool = False) -> ModelEntry:
    """Register ``entry`` under its name and aliases (``replace``: a model of that name may
    be replaced, e.g. in tests). Its parameters become known to the ``--param`` parser.
    The built-in models are registered first (so that a name of theirs is taken)."""
    from ..parameters import declare

    if not getattr(_LOADING, "depth", 0):  # (not a built-in module registering its own)
        _load_builtins()
    if not isinstance(entry, ModelEntry):
        raise TypeError(f"register_model takes a ModelEntry, got {type(entry).__name__}")
    if not replace and (entry.name in _ENTRIES or entry.name in _ALIASES):
        raise ValueError(f"a model named '{entry.name}' is already registered")
    declare(*entry.parameters)
    _ENTRIES[entry.name] = entry
    for a in entry.aliases:
        _ALIASES[a] = entry.name
    return entry


def unregister_model(name: str) -> None:
    """Remove model ``name`` and its aliases from the registry (e.g. a test's toy model)."""
    entry = get_model(name)
    del _ENTRIES[entry.name]
    for a in entry.aliases:
        _ALIASES.pop(a, None)


def get_model(name: str) -> ModelEntry:
    """The entry of model ``name`` (an alias works too); a one-line error naming the known
    models otherwise. A built-in model's name imports its module only (:data:`BUILTINS`)."""
    key = _ALIASES.get(name, name) if isinstance(name, str) else name
    if key not in _ENTRIES:
        _load_builtins([m for m, names in BUILTINS.items() if key in names])
    if key not in _ENTRIES:
        _load_builtins()
        key = _ALIASES.get(name, name) if isinstance(name, str) else name
    if key not in _ENTRIES:
        raise ParameterError(f"unknown model '{name}' (models: {', '.join(model_names())})")
    return _ENTRIES[key]


def model_names() -> list[str]:
    """The canonical names of the registered models, sorted."""
    _load_builtins()
    return sorted(_ENTRIES)


def entries() -> list[ModelEntry]:
    """Every registered entry, sorted by name."""
    return [_ENTRIES[k] for k in model_names()]

