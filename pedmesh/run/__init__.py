"""Running models through the shared output contract (``pedmesh run``)."""

from .driver import RunInterrupted, run_model
from .output import RunWriter, evacuation_times, evacuation_times_from_curve
from .results import RunResult
from .safety import safety_measures

__all__ = ["RunInterrupted", "RunResult", "RunWriter", "evacuation_times",
           "evacuation_times_from_curve", "run_model", "safety_measures"]
