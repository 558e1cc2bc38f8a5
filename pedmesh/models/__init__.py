"""The models: the social force model (:mod:`pedmesh.models.sfm`) and the continuum models
(:mod:`pedmesh.models.continuum`) side by side, behind one run protocol
(:class:`RunModel`) and one registry (:func:`register_model`, :func:`get_model`).

The built-in models register themselves on the registry's first use, each run importing
its own model only (:data:`~pedmesh.models.registry.BUILTINS`).
"""

from .protocol import DenseFrames, RunModel
from .registry import (CONTINUUM, PARTICLES, ModelEntry, entries, get_model, model_names,
                       register_model, unregister_model)

__all__ = ["CONTINUUM", "PARTICLES", "DenseFrames", "ModelEntry", "RunModel", "entries",
           "get_model", "model_names", "register_model", "unregister_model"]
