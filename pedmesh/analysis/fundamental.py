"""The local density-flow diagram (paper, fundamental diagram section)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from ..parameters import DEFAULTS as D

__all__ = ["DensityFlowDiagram", "density_flow_diagram", "reference_flow", "PAPER_BINS"]

#: density bins of the paper: 0 to 10.5 ped/m^2 in steps of 0.03
PAPER_BINS = np.round(np.arange(0.0, 10.5 + 1e-9, 0.03), 10)


@dataclass(frozen=True)
class DensityFlowDiagram:
    """Mean flow per density bin."""

    bin_edges: np.ndarray  #: [ped/m^2]
    centers: np.ndarray  #: [ped/m^2]
    mean_flow: np.ndarray  #: [ped/(m s)], NaN where a bin is empty
    counts: np.ndarray


def density_flow_diagram(*, density: np.ndarray, flow: np.ndarray,
                         bins: np.ndarray = PAPER_BINS) -> DensityFlowDiagram:
    """Group (density, flow) samples (e.g. every cell every second) into density bins and
    average the flow in each. Samples outside the bins are dropped; empty bins get NaN."""
    d = np.asarray(density, float).ravel()
    f = np.asarray(flow, float).ravel()
    k = np.digitize(d, bins) - 1
    ok = (k >= 0) & (k < len(bins) - 1)
    counts = np.bincount(k[ok], minlength=len(bins) - 1)
    sums = np.bincount(k[ok], weights=f[ok], minlength=len(bins) - 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(counts > 0, sums / np.maximum(counts, 1), np.nan)
    return DensityFlowDiagram(bins, 0.5 * (bins[1:] + bins[:-1]), mean, counts)


def reference_flow(*, density: np.ndarray, U_f: float = D['U_f'],
                   beta: float = D['beta']) -> np.ndarray:
    """f_d = rho U_e(rho) = rho U_f exp(-beta rho) [ped/(m s)]."""
    d = np.asarray(density, float)
    return d * U_f * np.exp(-beta * d)
