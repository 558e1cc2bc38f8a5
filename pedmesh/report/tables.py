"""The report's tables of values as HTML: the key numbers, a comparison's distances, the
crowd-safety measures, exits, levels and stairs, and a run's settings."""

from __future__ import annotations

import html
from typing import Mapping, Sequence

from .html import attr, esc, html_table
from .load import Run
from .measures import los_scale
from .text import exact, float_or_none, is_num, number, people, seconds, unit_text

__all__ = ["key_numbers", "comparison_table", "safety_table", "exit_table",
           "level_safety_table", "stair_table", "settings_block"]

#: the densities [/m²] of the safety measures' area-time and time above (their keys)
_THRESHOLDS = ("2", "4", "6")


def key_numbers(runs: Sequence[Run]) -> str:
    """T50/T90/T100 and the counts per run (one row each), with the exact values of
    summary.json in each cell's title."""
    rows = []
    for r in runs:
        s = r.s
        cells = [esc(r.label), esc(r.s.get("model")), esc(r.status),
                 people(s.get("n_initial")), people(s.get("n_evacuated"))]
        for k in ("t_evac_50", "t_evac_90", "t_evac_100"):
            v = s.get(k)
            cells.append(f'<span class="num" title="summary.json: {attr(exact(v))}">'
                         f"{seconds(v)}</span>")
        pk = ((r.safety or {}).get("peak_density") or {}).get("value")
        if is_num(pk):
            cells.append(f"{number(pk, 3)}")
        elif r.frames is not None:
            cells.append(f"{r.frames.peak[0].max():.2f} (cell)")
        else:
            cells.append("–")
        wall = s.get("wall_time_s")
        cells.append(f"{wall:.1f} s" if is_num(wall) else "–")
        rows.append(cells)
    table = html_table(["run", "model", "status", "people", "out", "T50", "T90", "T100",
                        "peak density [ped/m²]", "computing time"], rows, "numbers")
    return table


def comparison_table(comp: Mapping) -> str:
    rows = comp["rows"]
    keys = [k for k in rows[0] if k not in ("label", "model", "t_evac_50", "t_evac_90",
                                             "t_evac_100", "steps", "wall_time_s")]
    if not keys:
        return ""
    head = ["model"] + [esc(k) for k in keys]
    body = [[esc(r.get("label"))] + [number(float_or_none(r.get(k)), 3)
                                       if float_or_none(r.get(k)) is not None
                                       else esc(r.get(k) or "–") for k in keys] for r in rows]
    return ("<p>Distances from the first model, as <code>comparison.csv</code> of "
            f"<code>{esc(comp['path'])}</code> has them (the mean |N<sub>out</sub>(t) - "
            "N<sub>ref</sub>(t)|/N of the evacuation curves, the T90 difference [s], the "
            "relative difference of the outflow curves and the L1 distance of the density "
            "fields / N at the times in the column names):</p>" + html_table(head, body))


def _safety_rows(sf: Mapping) -> list[tuple[str, str]]:
    """(measure, value) rows of a run's safety section."""
    rows: list[tuple[str, str]] = []
    pk = sf.get("peak_density") or {}
    if pk:
        unit = unit_text(pk.get("unit") or "/m²")
        where = ""
        if is_num(pk.get("x")) and is_num(pk.get("y")):
            where = f" at x = {number(pk['x'])} m, y = {number(pk['y'])} m"
        over = (f' (<span title="{html.escape(unit_text(pk["over"]))}">averaged over 1 m²</span>)'
                if pk.get("over") is not None else "")
        if pk.get("level") is not None:  # a building's: in that level's plan
            where = f" on level '{esc(pk['level'])}'" + where
        rows.append((f"peak density{over}",
                     f"{number(pk.get('value'))} {esc(unit)} at t = {number(pk.get('t'))} s"
                     + where))
    unit = unit_text(sf.get("area_time_unit") or "m² s")
    for k in _THRESHOLDS:
        v = (sf.get("area_time_above") or {}).get(k)
        if v is not None or sf.get("area_time_above"):
            rows.append((f"area-time above {k} /m²", f"{number(v)} {esc(unit)}"))
    for k in _THRESHOLDS:
        v = (sf.get("time_above") or {}).get(k)
        if v is not None or sf.get("time_above"):
            rows.append((f"time above {k} /m²", f"{number(v)} s"))
    los = sf.get("level_of_service") or {}
    if los:
        counts = los.get("cells_by_worst") or {}
        text = f"worst {esc(los.get('worst', '–'))}"
        if counts:
            text += "; cells by their worst level: " + ", ".join(
                f"{esc(k)}: {number(v)}" for k, v in counts.items())
        rows.append((f"level of service (Fruin, {los_scale(sf)})", text))
    if "crowd_pressure" in sf:
        cp = sf.get("crowd_pressure")
        if isinstance(cp, dict):
            where = ""
            if is_num(cp.get("x")) and is_num(cp.get("y")):
                where = f" at x = {number(cp['x'])} m, y = {number(cp['y'])} m"
            if cp.get("level") is not None:  # a building's: in that level's plan
                where = f" on level '{esc(cp['level'])}'" + where
            rows.append(('<span title="the local density times the variance of the people\'s '
                         'velocities (Helbing, Johansson &amp; Al-Abideen 2007); crowd '
                         'turbulence was seen above about 0.02 /s²">crowd pressure ρ Var(v) '
                         '(largest)</span>',
                         f"{number(cp.get('max'))} {esc(unit_text(cp.get('unit') or ''))} at t = "
                         f"{number(cp.get('t'))} s{where}"))
        elif "levels" in sf:  # (a continuum's building run, or an older run folder)
            rows.append(("crowd pressure ρ Var(v)", "not recorded for this building run"))
        else:
            rows.append(("crowd pressure ρ Var(v)", "not applicable (no particle velocities)"))
    for name, e in (sf.get("exits") or {}).items():
        if isinstance(e, dict):
            # (people whole: a continuum's fractional mass is exact in summary.json)
            when = (f", first at {number(e.get('first'))} s, last at {number(e.get('last'))} s"
                    if is_num(e.get("first")) else "")
            rows.append((f"exit '{esc(name)}'", f"{people(e.get('people'))} people{when}"))
    ct = sf.get("clear_times") or {}
    for group, what in (("start_areas", "start area"), ("measurement_areas",
                                                          "measurement area")):
        for name, v in (ct.get(group) or {}).items():
            rows.append((f"{what} '{esc(name)}' clear after",
                         f"{number(v)} s" if v is not None else "not cleared"))
    return rows


def safety_table(runs: Sequence[Run]) -> str:
    if all(r.safety is None for r in runs):
        why = "; ".join(dict.fromkeys((f"{esc(r.label)}: " if len(runs) > 1 else "")
                                      + esc(r.safety_missing) for r in runs))
        return ('<p class="na">Crowd-safety measures: <b>not available</b> (' + why
                + "). The maps above are computed from the saved density frames.</p>")
    per = [dict(_safety_rows(r.safety)) if r.safety is not None else None for r in runs]
    keys: list[str] = []
    for d in per:
        for k in d or {}:
            if k not in keys:
                keys.append(k)
    if len(runs) == 1:
        return html_table(["measure", "value"], [(k, per[0][k]) for k in keys], "safety")
    body = [[k] + [(d.get(k, "–") if d is not None else
                    f'not available ({esc(r.safety_missing)})') for d, r in zip(per, runs)]
            for k in keys]
    return html_table(["measure"] + [esc(r.label) for r in runs], body, "safety")


def exit_table(runs: Sequence[Run]) -> str:
    rows = []
    for r in runs:
        ex = r.exits()
        total = sum(float(e["people"]) for e in ex if is_num(e["people"]))
        for e in ex:
            share = (f"{100 * float(e['people']) / total:.0f} %"
                     if is_num(e["people"]) and total > 0 else "–")
            row = [f"'{esc(e['name'])}'", people(e["people"]), share,
                   seconds(e["first"], "–"), seconds(e["last"], "–")]
            rows.append(([esc(r.label)] if len(runs) > 1 else []) + row)
    head = (["run"] if len(runs) > 1 else []) + ["exit", "people", "share",
                                                  "first passage", "last passage"]
    return html_table(head, rows)


def level_safety_table(runs: Sequence[Run]) -> str:
    """Per level of a building run: peak density, area-time above the thresholds, worst
    level of service ("" if no run has levels)."""
    rows = []
    for r in runs:
        levels = (r.safety or {}).get("levels")
        if not isinstance(levels, dict):
            continue
        for name, sf in levels.items():
            if not isinstance(sf, dict):
                continue
            pk = sf.get("peak_density") or {}
            at = sf.get("area_time_above") or {}
            row = [f"'{esc(name)}'",
                   f"{number(pk.get('value'), 3)} /m² at {seconds(pk.get('t'), '?')}"
                   if is_num(pk.get("value")) else "–"]
            row += [number(at.get(k), 3) for k in _THRESHOLDS]
            row.append(esc((sf.get("level_of_service") or {}).get("worst", "–")))
            rows.append(([esc(r.label)] if len(runs) > 1 else []) + row)
    if not rows:
        return ""
    head = (["run"] if len(runs) > 1 else []) + (
        ["level", "peak density (1 m²)"] + [f"area-time above {k} /m² [m² s]"
                                            for k in _THRESHOLDS] + ["worst level of service"])
    return ("<h3>Per level</h3>" + html_table(head, rows, "safety")
            + "<p>The same measures on each level alone (positions in the level's own plan); "
            "the stairs' peak densities are in the stair table.</p>")


def stair_table(runs: Sequence[Run]) -> str:
    """Per stair of a building run: people (down / up), first and last use, peak flow and
    peak density ("" if no run has stairs)."""
    rows = []
    for r in runs:
        stairs = r.summary.get("stairs")
        if not isinstance(stairs, dict):
            continue
        for name, u in stairs.items():
            if not isinstance(u, dict):
                continue
            flow = u.get("peak_flow")
            rho = u.get("peak_density")
            row = [f"'{esc(name)}'", people(u.get("people")),
                   f"{people(u.get('down'))} / {people(u.get('up'))}",
                   seconds(u.get("first"), "–"), seconds(u.get("last"), "–"),
                   (f"{flow:.2f} /s at {seconds(u.get('peak_flow_t'), '?')}"
                    if is_num(flow) and flow > 0 else "–"),
                   (f"{rho:.2f} /m² at {seconds(u.get('peak_density_t'), '?')}"
                    if is_num(rho) and rho > 0 else "–")]
            rows.append(([esc(r.label)] if len(runs) > 1 else []) + row)
    if not rows:
        return ""
    head = (["run"] if len(runs) > 1 else []) + [
        "stair", "people", "down / up", "first on", "last on",
        "peak flow (10 s)", "peak density"]
    return html_table(head, rows)


def settings_block(run: Run) -> str:
    s = run.s
    st = run.result.settings
    prov = [
        ("model", esc(s.get("model"))),
        ("status", esc(run.status) + (f" ({esc(s.get('error'))})" if s.get("error") else "")),
        ("parameter preset", esc(st.get("preset") or "–")),
        ("overrides", esc(", ".join(f"{k}={v}" for k, v in (st.get("overrides") or {}).items())
                          or "none")),
        ("model options", esc(", ".join(f"{k}={v}" for k, v in
                                        (st.get("model_options") or {}).items()) or "none")),
        ("room file", esc(s.get("geometry") or "–")),
        ("room name", esc(s.get("room") or "–")),
        ("room file SHA-256", f"<code>{esc(st.get('room_sha256') or '–')}</code>"),
        ("end time t_end", f"{number(s.get('t_end'))} s"),
        ("mesh", esc(", ".join(f"{k} = {v}" for k, v in (s.get("mesh") or {}).items()))),
        ("pedmesh version", esc(s.get("pedmesh_version") or st.get("pedmesh_version"))),
        ("time steps", esc(s.get("steps", "–"))),
        ("computing time", f"{s['wall_time_s']:.1f} s" if is_num(s.get("wall_time_s"))
         else "–"),
        ("run folder", f"<code>{esc(run.path)}</code>"),
    ]
    from ..parameters import PARAMETERS

    units = s.get("units") or {}
    prows = []
    for k, v in (s.get("parameters") or {}).items():
        decl = PARAMETERS.get(k)
        unit = units.get(k, decl.unit if decl is not None else "")
        prows.append([f"<code>{esc(k)}</code>", esc(exact(v) if not isinstance(v, str)
                                                    else v),
                      esc(unit or "–"), esc(decl.description if decl is not None else "")])
    warn = list(s.get("warnings") or [])
    notes = list(dict.fromkeys(run.notes))
    wl = "".join(f"<li>{esc(w)}</li>" for w in warn) or "<li class='none'>none</li>"
    nl = "".join(f"<li>{esc(w)}</li>" for w in notes)
    scalars = [(k, v) for k, v in s.items() if not isinstance(v, (dict, list))]
    return (
        html_table(["setting", "value"], prov, "settings")
        + f"<h4>Warnings of the run</h4><ul class='warnings'>{wl}</ul>"
        + (f"<h4>Notes of this report</h4><ul class='warnings'>{nl}</ul>" if nl else "")
        + "<details><summary>Every parameter with its unit "
        f"({len(prows)})</summary>"
        + html_table(["parameter", "value", "unit", "meaning"], prows, "params") + "</details>"
        + "<details><summary>The numbers of summary.json as recorded</summary>"
        + html_table(["key", "value"],
                     [(f"<code>{esc(k)}</code>", f"<code>{esc(exact(v))}</code>")
                      for k, v in scalars], "raw") + "</details>")

