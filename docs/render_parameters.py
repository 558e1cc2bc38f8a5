"""Write the parameter tables from pedmesh's parameter declarations.

    python docs/render_parameters.py     # writes docs/_generated/parameters.md

``docs/conf.py`` runs it at every build. Every value comes from the declarations
(:mod:`pedmesh.parameters`), the model registry (:mod:`pedmesh.models`) and the presets
(:mod:`pedmesh.presets`), the same objects the command line, the runs and ``pedmesh
presets`` read, so the page cannot drift from the code.
"""

from __future__ import annotations

from pathlib import Path

DOCS = Path(__file__).resolve().parent
OUT = DOCS / "_generated" / "parameters.md"


def _cell(v) -> str:
    if v is None:
        return "None"
    if isinstance(v, bool):
        return str(int(v))
    if isinstance(v, str):
        return f"`{v}`" if v else "`''`"
    return f"{v:g}" if isinstance(v, float) else str(v)


def _esc(text: str) -> str:
    return text.replace("|", "\\|").replace("*", "\\*")


def render() -> str:
    from pedmesh import parameters as P
    from pedmesh.models import entries
    from pedmesh.presets import PRESETS

    groups = [
        ("The paper's Table 1", P.TABLE1),
        ("The desired-speed law", P.SPEED_LAW),
        ("The social force model's dense-crowd terms", P.SFM_TERMS),
        ("Routes", P.ROUTES),
        ("The social force model's numerics", P.SFM_NUMERICS),
        ("Output", P.RUN_OUTPUT),
        ("The continuum models' physics", P.CONTINUUM),
        ("The finite-volume numerics", P.FV_NUMERICS),
    ]
    models = entries()
    takes = {p.name: [e.name for e in models if p.name in e.parameter_names]
             for _, g in groups for p in g}
    out = []
    for title, params in groups:
        out += [f"## {title}", "",
                "| parameter | default | unit | allowed | meaning | source | models |",
                "|---|---|---|---|---|---|---|"]
        for p in params:
            m = takes[p.name]
            who = "all" if len(m) == len(models) else ", ".join(m) or "-"
            out.append(f"| `{p.name}` | {_cell(p.default)} | {_esc(p.unit)} | "
                       f"{_esc(p.bounds)} | {_esc(p.description)} | {_esc(p.source)} | "
                       f"{who} |")
        out.append("")
    out += ["## Values under each preset", "",
            "A preset sets only what it lists, and only for the models that take the "
            "parameter; everything else keeps the default above. Continuum models take a "
            "preset's continuum values over the others.", ""]
    for name, pre in PRESETS.items():
        out += [f"### `{name}`", "", _esc(pre.description), "",
                "| parameter | value | unit | source |", "|---|---|---|---|"]
        for k, v in pre.values.items():
            val = v.value
            if k == "calibration":
                val = Path(str(val)).name
            out.append(f"| `{k}` | {_cell(val)} | {_esc(v.unit)} | {_esc(v.source)} |")
        for k, v in pre.continuum.items():
            out.append(f"| `{k}` (continuum) | {_cell(v.value)} | {_esc(v.unit)} | "
                       f"{_esc(v.source)} |")
        out.append("")
    out += ["## Models", "", "| model | aliases | scale | options | description |",
            "|---|---|---|---|---|"]
    for e in models:
        out.append(f"| `{e.name}` | {', '.join(e.aliases) or '-'} | {e.scale} | "
                   f"{', '.join(sorted(e.options)) or '-'} | {_esc(e.description)} |")
    return "\n".join(out) + "\n"


def main() -> Path:
    OUT.parent.mkdir(parents=True, exist_ok=True)
    text = render()
    if not OUT.exists() or OUT.read_text(encoding="utf-8") != text:
        OUT.write_text(text, encoding="utf-8")
    return OUT


if __name__ == "__main__":
    print(main())
