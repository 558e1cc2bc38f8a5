"""Numbers, times and units as the report writes them (plain text, no HTML)."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

__all__ = ["number", "seconds", "people", "unit_text", "exact", "is_num", "float_or_none"]


def number(v: Any, digits: int = 4) -> str:
    """A number for people: ``digits`` significant digits, no exponent below 10^6; '-' for
    None; other values as text."""
    if v is None:
        return "–"
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        return str(v)
    f = float(v)
    if not math.isfinite(f):
        return "–"
    if float(f).is_integer() and abs(f) < 1e15:
        return f"{int(f):,}".replace(",", " ") if abs(f) >= 1e4 else str(int(f))
    if abs(f) >= 10 ** digits:
        return f"{f:,.0f}".replace(",", " ")
    return f"{f:.{digits}g}"


def seconds(v: Any, missing: str = "not reached") -> str:
    """A time [s] as ``pedmesh run`` prints it (one decimal)."""
    if v is None or not isinstance(v, (int, float)) or not math.isfinite(float(v)):
        return missing
    return f"{float(v):.1f} s"


def people(v: Any) -> str:
    """People as a whole number for display (a continuum model's fractional mass is kept
    exact in its files)."""
    if v is None:
        return "–"
    return str(int(round(float(v))))


def unit_text(u: Any) -> str:
    """A unit as the report writes units: m² rather than m^2."""
    return str(u).replace("ped/m^2", "/m²").replace("^2", "²")


def exact(v: Any) -> str:
    """A value exactly as json writes it (and so as summary.json has it)."""
    return json.dumps(v)


def is_num(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(float(v))


def float_or_none(text: Any) -> float | None:
    try:
        f = float(text)
    except (TypeError, ValueError):
        return None
    return f if math.isfinite(f) else None
