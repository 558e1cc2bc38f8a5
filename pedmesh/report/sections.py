"""The sections of the page: those of a group of runs shown side by side
(:func:`runs_sections`) and those of an ensemble (:func:`ensemble_sections`)."""

from __future__ import annotations

import json
from typing import Mapping, Sequence

import numpy as np

from ..io.run_folder import SUMMARY
from .figures import (VMAX, bands_figure, evac_figure, flow_figure, maps_figure, plan_figure,
                      snapshots, spread_figure)
from .html import Page, esc, html_table, img, plausibility_html, slider
from .load import Ensemble, Run
from .measures import FRUIN_LEVELS, LOS, los_scale
from .plausibility import run_checks
from .tables import (comparison_table, exit_table, key_numbers, level_safety_table,
                     safety_table, settings_block, stair_table)
from .text import is_num, number, seconds

__all__ = ["runs_sections", "ensemble_sections"]


def runs_sections(page: Page, runs: Sequence[Run], comparisons: Sequence[Mapping],
                  frames: int, *, prefix: str = "", level: int = 2) -> None:
    """The sections of a group of runs shown side by side (one run: its own report);
    ``level``: of their headings (2: in the page's navigation)."""
    single = len(runs) == 1

    def section(anchor: str, title: str, body: str) -> None:
        page.section(prefix + anchor, title, body, level)

    body = (key_numbers(runs)
            + "<p>T50, T90 and T100: the times at which half, 90 % and all of the people "
            "were out, as the runs recorded them (hover for the exact value). Peak density: "
            "the safety measure (over 1 m² or as stated) where the run has it, else the "
            "largest cell value of the saved frames.</p>")
    for comp in comparisons:
        body += comparison_table(comp)
    section("numbers", "Key numbers", body)
    section("plausibility", "Plausibility check",
            plausibility_html([(r.label, run_checks(r)) for r in runs]))
    seen: dict = {}
    figs = ""
    for r in runs:
        key = ((r.s.get("settings") or {}).get("room_sha256"), r.s.get("geometry"))
        if key in seen:
            continue
        seen[key] = r
        figs += img(plan_figure(r), f"plan of {r.s.get('room') or r.label}")
    building = any(r.frames is not None and r.frames.layout is not None for r in seen.values())
    section("plan", "Room plan", figs
            + "<p>Walls in black, exits in green (named), obstacles grey, the start areas "
            "blue with their people, measurement areas and lines purple.</p>"
            + ("<p>A building: one panel per level, in its own plan (stacked floors apart); "
               "each stair where it is, dashed, on both levels it joins, labelled with the "
               "level it leads to (its cells drawn on its bottom level's panel); the maps "
               "below are drawn the same way.</p>" if building else ""))
    section("evacuation", "Evacuation", img(evac_figure(runs),
                                            "evacuation curve: people out against time"))
    flow = flow_figure(runs)
    section("exits", "Exit usage", exit_table(runs)
                 + (img(flow, "flow through the exits against time") if flow else "")
                 + ("<p>People per exit as the run counted them (a continuum model's "
                    "integrated outflow, rounded to whole people); first and last passage "
                    "where known.</p>" if any(r.s.get("model") != "sfm" for r in runs) else
                    "<p>People per exit as the run counted them; first and last passage.</p>"))
    stairs = stair_table(runs)
    if stairs:
        section("stairs", "Stair use", stairs + (
            "<p>Per stair: the people who stepped onto it (down from its top level, up "
            "from its bottom level), when the first stepped on and the last was on it, the "
            "most people stepping on within 10 s (per second), and the most people on it "
            "at once over its area. A continuum model's people are its inflow through "
            "the stair's edges, integrated: an estimate, within 7 % in our tests.</p>"))
    maps = ""
    peak = maps_figure(runs, "peak")
    if peak:
        maps += "<h3>Peak density</h3>" + img(peak, "peak density map")
    los = maps_figure(runs, "los")
    if los:
        scale = los_scale(runs[0].safety)
        edges = FRUIN_LEVELS[scale]
        bounds = ", ".join(f"{a} up to {e:.2f}" for a, e in zip(LOS, edges)) + \
            f", F above {edges[-1]:.2f} ped/m²"
        maps += ("<h3>Level of service</h3>" + img(los, "level of service map")
                 + f"<p>Fruin's levels of service for {scale}s by density: {bounds} "
                 "(Fruin 1971, his areas per person in m²), of each cell's peak density: "
                 "the worst level the cell had.</p>")
    if not maps:
        maps = '<p class="na">No density frames were saved, so there are no maps.</p>'
    maps += "<h3>Crowd-safety measures</h3>" + safety_table(runs) + level_safety_table(runs)
    section("density", "Density and safety", maps)
    images, labels = snapshots(runs, frames)
    section("snapshots", "Density over time",
                 slider(page.uid("snap"), images, labels, "density snapshot")
                 + ("<p>Move the slider (or press play) to step through the saved frames. "
                    + ("Dots: the pedestrians. " if any(r.ped_frames for r in runs) else "")
                    + f"Colours saturate at {VMAX:g} ped/m².</p>" if images else ""))
    body = ""
    for r in runs:
        inner = settings_block(r)
        body += (inner if single else
                 f"<details><summary><b>{esc(r.label)}</b></summary>{inner}</details>")
    section("settings", "Settings and provenance", body)


def ensemble_sections(page: Page, ens: Ensemble, frames: int, idx: int) -> str:
    """The sections of an ensemble; returns its summary sentence."""
    pre = f"ens{idx}-"
    pts = ens.points
    rows = []
    for pt in pts:
        row = [esc(ens.point_label(pt)), f"{pt.get('finished', 0)} of {pt.get('members', 0)}"]
        for k in ("t_evac_50", "t_evac_90", "t_evac_100"):
            st = pt.get(k) or {}
            row.append(" / ".join(seconds(st.get(q), "–") for q in ("p5", "p50", "p95")))
            mean = seconds(st.get("mean"), "–")
            row.append(f"{mean} ± {st['std']:.1f} s" if is_num(st.get("std")) else mean)
        rows.append(row)
    table = html_table(["sweep point", "finished", "T50 p5 / p50 / p95", "T50 mean ± sd",
                        "T90 p5 / p50 / p95", "T90 mean ± sd", "T100 p5 / p50 / p95",
                        "T100 mean ± sd"], rows, "numbers")
    meta = ens.meta
    desc = (f"{esc(meta.get('model', '?'))} on {esc(meta.get('geometry', '?'))}, "
            f"{esc(meta.get('members', '?'))} members per point, seed {esc(meta.get('seed'))}"
            if meta else "no ensemble.json (percentiles computed from ensemble.csv)")
    body = (f"<p>{desc}. Percentiles over the finished members "
            "(5 %, median, 95 %), as ensemble.json has them.</p>" + table)
    bands = bands_figure(ens)
    if bands:
        body += (img(bands, "evacuation bands") + "<p>The median evacuation curve of each "
                 "sweep point and its 5-95 % band: at each time, 90 % of the members had "
                 "between the band's lower and upper number of people out.</p>")
    spread = spread_figure(ens)
    if spread:
        body += img(spread, "evacuation times of the members")
    # the members' safety measures, where they have them
    srows = []
    for r in ens.rows:
        d = ens.member_dir(r["member"])
        try:
            s = json.loads((d / SUMMARY).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        sf = s.get("safety")
        if isinstance(sf, dict):
            pk = (sf.get("peak_density") or {}).get("value")
            ta = (sf.get("time_above") or {}).get("4")
            srows.append((pk, ta))
    if srows:
        pk = [v for v, _ in srows if is_num(v)]
        ta = [v for _, v in srows if is_num(v)]

        def pct(v):
            if not v:
                return "–"
            a, b, c = np.percentile(v, [5, 50, 95])
            return f"{number(a, 3)} / {number(b, 3)} / {number(c, 3)}"

        body += ("<h3>Crowd-safety measures over the members</h3>"
                 + html_table(["measure", "p5 / p50 / p95"],
                              [("peak density [ped/m²]", pct(pk)),
                               ("time above 4 /m² [s]", pct(ta))]))
    else:
        body += ('<p class="na">Crowd-safety measures over the members: not available (the '
                 "members were made before pedmesh recorded them).</p>")
    cols = list(ens.rows[0]) if ens.rows else []
    mrows = [[esc(r.get(c, "")) for c in cols] for r in ens.rows]
    body += ("<details><summary>Every member (ensemble.csv)</summary>"
             + html_table([esc(c) for c in cols], mrows, "members") + "</details>")
    page.section(f"{pre}ensemble", f"Ensemble {ens.label}", body)
    typ = ens.typical
    sentence = ""
    if pts:
        st = pts[0]
        t100 = st.get("t_evac_100") or {}
        t90 = st.get("t_evac_90") or {}
        sentence = (f"Ensemble {esc(ens.label)} ({esc(ens.point_label(st))}, "
                    f"{st.get('finished', 0)} finished members): everyone out after "
                    f"{seconds(t100.get('p50'))} in the median (5-95 %: {seconds(t100.get('p5'))} "
                    f"to {seconds(t100.get('p95'))}); 90 % out after {seconds(t90.get('p50'))} "
                    f"(5-95 %: {seconds(t90.get('p5'))} to {seconds(t90.get('p95'))}).")
        if len(pts) > 1:
            sentence += f" {len(pts)} sweep points; see the table."
    if typ is not None:
        page.section(f"{pre}typical", f"A typical member: {typ.label}",
                     "<p>The member of the first sweep point whose T90 is nearest the median, "
                     "shown in full.</p>")
        runs_sections(page, [typ], [], frames, prefix=f"{pre}typ-", level=3)
    return sentence

