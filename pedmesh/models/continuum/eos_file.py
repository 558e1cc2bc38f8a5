"""Equation-of-state files: the measured SFM pressure table and its fit, as written by
``pedmesh calibrate`` (see :mod:`pedmesh.calibration`) and read by the ``eos`` model.

This module sits below both: the model reads files through it and the calibration writes
them through it, so neither imports the other.
"""

from __future__ import annotations

import json
from pathlib import Path

from ...errors import PedmeshError

__all__ = ["EOS_FORMAT", "DEFAULT_EOS", "load_eos", "save_eos"]

EOS_FORMAT = "pedmesh-eos"
#: the calibration shipped for the default (Table 1) parameters
DEFAULT_EOS = Path(__file__).resolve().parents[2] / "data" / "eos_default.json"


def save_eos(cal: dict, path: str | Path) -> Path:
    path = Path(path)
    path.write_text(json.dumps(cal, indent=1) + "\n", encoding="utf-8")
    return path


def load_eos(path: str | Path | None = None) -> dict:
    """Read a calibration file (default: the one shipped for Table 1's parameters)."""
    p = Path(path) if path else DEFAULT_EOS
    if not p.exists():
        raise PedmeshError(f"{p}: no such calibration file (run 'pedmesh calibrate')")
    try:
        cal = json.loads(p.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise PedmeshError(f"{p}: not a calibration file ({exc.msg})") from None
    except UnicodeDecodeError:
        raise PedmeshError(f"{p}: not a calibration file (not UTF-8 text; 'pedmesh "
                           "calibrate' writes JSON)") from None
    except IsADirectoryError:
        raise PedmeshError(f"{p}: is a directory, not a calibration file") from None
    if not isinstance(cal, dict) or cal.get("format") != EOS_FORMAT:
        raise PedmeshError(f"{p}: not a pedmesh equation-of-state file")
    if cal.get("status") == "incomplete" or "fit" not in cal:
        raise PedmeshError(f"{p}: incomplete calibration ({len(cal.get('table', []))} "
                           "densities measured; the run was interrupted): rerun 'pedmesh "
                           "calibrate'")
    fit = cal["fit"]
    try:
        _check_fit(fit)
    except (KeyError, TypeError, ValueError) as exc:
        raise PedmeshError(f"{p}: malformed fit in the calibration file ({exc})") from None
    return cal


def _check_fit(fit: dict) -> None:
    """Raise if ``fit`` is not a usable monotone table."""
    from .barotropic import PressureLaw

    PressureLaw.table(fit["rho"], fit["p"], fit["dp"])
