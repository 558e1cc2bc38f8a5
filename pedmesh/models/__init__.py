"""The models: the social force model (:mod:`pedmesh.models.sfm`) and the continuum models
(:mod:`pedmesh.models.continuum`) side by side, behind one run protocol
(:class:`RunModel`) and one registry (:func:`register_model`, :func:`get_model`).

Importing this package registers the built-in models.
"""

from .protocol import DenseFrames, RunModel
from .registry import (CONTINUUM, PARTICLES, ModelEntry, entries, get_model, model_names,
                       register_model, unregister_model)
from . import sfm as _sfm  # noqa: E402,F401  (registers sfm)
from . import continuum as _continuum  # noqa: E402,F401  (registers the continuum models)

__all__ = ["CONTINUUM", "PARTICLES", "DenseFrames", "ModelEntry", "RunModel", "entries",
           "get_model", "model_names", "register_model", "unregister_model"]
