"""Running models through the shared output contract (``pedmesh run``)."""

from .driver import RunInterrupted, run_model
from .models import MODELS, get_model, register_model
from .output import RunWriter, evacuation_times, evacuation_times_from_curve
from .results import RunResult

__all__ = ["MODELS", "RunInterrupted", "RunResult", "RunWriter", "evacuation_times",
           "evacuation_times_from_curve", "get_model", "register_model", "run_model"]
