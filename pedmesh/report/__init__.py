"""Self-contained HTML reports of runs, comparisons and ensembles (``pedmesh report``).

:func:`write_report` turns one or more folders that pedmesh wrote into one HTML page that a
person reads in any browser, offline: every plot is an inline PNG (a ``data:`` URI), the
little JavaScript that drives the time slider is inline, and nothing is fetched from
anywhere. A folder is

* a run folder (``pedmesh run``: ``summary.json``, ``evacuation.csv``, ``outflow.csv``,
  ``density.pvd``; see :mod:`pedmesh.run.output`),
* a compare folder (``pedmesh compare``: ``comparison.csv`` and a run folder per model), or
* an ensemble folder (``pedmesh ensemble``: ``ensemble.csv``, ``ensemble.json`` and the
  members' run folders under ``members/``).

Several folders are shown side by side. The page holds a plain-language summary, a
plausibility check (the run's exit flows, peak density and walking speeds against what real
crowds were measured to do, and its parameter preset; :mod:`pedmesh.report.plausibility`),
the room plan, the evacuation curves with T50/T90/T100 (the numbers of ``summary.json``, never
recomputed), the exit usage, the peak-density and level-of-service maps, the crowd-safety
measures of ``summary.json`` (key ``safety``; "not available" for runs made before pedmesh
recorded them), density snapshots with a time slider, and every setting, parameter and
warning of the runs. Ensembles add the 5-95 % bands of the evacuation curves and the
percentiles of T50/T90/T100.

The peak-density map is the largest density each mesh cell had in the saved frames of
``density.pvd`` (the cell values; a particle model's vertex densities are averaged to the
cells); the level-of-service map classifies it with Fruin's thresholds
(:data:`FRUIN_LEVELS`). Both are drawn from the frames, for runs with and without the
safety measures.

The package's modules: :mod:`~pedmesh.report.load` (what it reads),
:mod:`~pedmesh.report.measures` and :mod:`~pedmesh.report.plausibility` (what it
computes), :mod:`~pedmesh.report.figures` (the pictures), :mod:`~pedmesh.report.html` (the
page), :mod:`~pedmesh.report.tables` (the tables of values),
:mod:`~pedmesh.report.sections` (the page's sections) and :mod:`~pedmesh.report.text`
(numbers as the report writes them).
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from .html import Page, esc
from .load import ReportError, folder_kind, load_folders
from .measures import FRUIN_LEVELS, run_sentences
from .plausibility import run_checks, summary_sentence
from .sections import ensemble_sections, runs_sections

__all__ = ["ReportError", "write_report", "build_report", "folder_kind", "FRUIN_LEVELS",
           "DEFAULT_FRAMES", "MAX_FRAMES"]

#: density snapshots on the slider unless asked otherwise
DEFAULT_FRAMES = 24
#: most snapshots the slider takes (each is an inline image)
MAX_FRAMES = 60


def build_report(folders: Sequence[str | Path], *, frames: int = DEFAULT_FRAMES,
                 title: str | None = None) -> str:
    """The HTML page of the run, compare and ensemble ``folders`` (see the module
    docstring); ``frames``: the most density snapshots on the slider."""
    if isinstance(frames, bool) or not isinstance(frames, (int, np.integer)) \
            or not 1 <= frames <= MAX_FRAMES:
        raise ReportError(f"frames must be a whole number from 1 to {MAX_FRAMES}, got "
                          f"{frames!r}")
    runs, comparisons, ensembles = load_folders(folders)
    if title is None:
        rooms = list(dict.fromkeys(
            [str(r.s.get("room") or r.path.name) for r in runs]
            + [str(e.typical.s.get("room")) if e.typical is not None and e.typical.s.get("room")
               else Path(str(e.meta.get("geometry") or e.label)).stem for e in ensembles]))
        what = (", ".join(r.label for r in runs) if len(runs) <= 4
                else f"{len(runs)} runs") if runs else ""
        if ensembles:
            what = ", ".join(filter(None, [what] + [f"ensemble {e.label}" for e in ensembles]))
        title = f"Evacuation report: {', '.join(rooms)} ({what})"
    page = Page(title)
    summary_parts: list[str] = []
    if runs:
        if len(runs) == 1:
            summary_parts += [f"<p>{esc(x)}</p>" for x in run_sentences(runs[0])
                              + [summary_sentence(run_checks(runs[0]))]]
        else:
            for r in runs:  # (the plausibility only where something is flagged)
                words = run_sentences(r)[:2]
                if run_checks(r).flagged:
                    words.append(summary_sentence(run_checks(r)))
                summary_parts.append(f"<p><b>{esc(r.label)}</b>: " + esc(" ".join(words))
                                     + "</p>")
        runs_sections(page, runs, comparisons, frames)
    for i, ens in enumerate(ensembles):
        sentence = ensemble_sections(page, ens, frames, i)
        if sentence:
            summary_parts.append(f"<p>{sentence}</p>")
    srcs = ", ".join(f"<code>{esc(f)}</code>" for f in folders)
    return page.html(f"From {srcs}.", "".join(summary_parts))


def write_report(folders: Sequence[str | Path], out: str | Path, *,
                 frames: int = DEFAULT_FRAMES, title: str | None = None) -> Path:
    """Write the report of ``folders`` (run, compare or ensemble folders) to the HTML file
    ``out`` and return its path (see :func:`build_report`)."""
    from ..io.files import write_whole
    from ..run.output import check_writable, write_error

    out = Path(out)
    if out.suffix.lower() not in (".html", ".htm"):
        raise ReportError(f"{out}: the report is an HTML page; use a .html suffix")
    check_writable(out)  # (before the minutes of reading and drawing)
    text = build_report(folders, frames=frames, title=title)
    try:
        return write_whole(out, text)
    except OSError as exc:
        raise write_error(out, exc) from None
