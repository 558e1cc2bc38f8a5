"""The page's HTML: escaping, tables, images and the time slider, the plausibility panel
(:func:`plausibility_html`), and the page itself (:class:`Page`: its sections, navigation,
styles and script)."""

from __future__ import annotations

import datetime as _dt
import html
import json
from typing import Any, Iterable, Sequence

from .._version import __version__
from .plausibility import Panel, method_sentences
from .text import is_num

__all__ = ["esc", "attr", "img", "html_table", "slider", "plausibility_html", "Page"]


def esc(v: Any) -> str:
    """Text for an element's content."""
    return html.escape(str(v), quote=False)


def attr(v: Any) -> str:
    """Text for an attribute's value (in double quotes)."""
    return html.escape(str(v), quote=True)


def img(uri: str, alt: str, cls: str = "plot") -> str:
    return f'<img class="{cls}" src="{uri}" alt="{attr(alt)}">'


def html_table(header: Sequence[str], rows: Iterable[Sequence[Any]], cls: str = "") -> str:
    head = "".join(f"<th>{h}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in rows)
    c = f' class="{cls}"' if cls else ""
    return f"<table{c}><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def slider(uid: str, images: list[str], labels: list[str], alt: str) -> str:
    if not images:
        return '<p class="na">No density frames were saved, so there are no snapshots.</p>'
    data = json.dumps({"images": images, "labels": labels}).replace("</", "<\\/")
    n = len(images)
    return (f'<div class="snapshots" id="{uid}">'
            f'<div class="controls"><button type="button" class="play" '
            f'aria-label="play">&#9654; play</button>'
            f'<input type="range" class="slider" min="0" max="{n - 1}" value="0" step="1" '
            f'aria-label="time of the snapshot">'
            f'<span class="snap-label">{esc(labels[0])}</span></div>'
            f'<img class="snap" src="{images[0]}" alt="{attr(alt)}">'
            f'<script type="application/json" class="snap-data">{data}</script></div>')


#: how each verdict of the plausibility panel is shown: mark and words
_VERDICTS = {"within": ("✓", "within"), "edge": ("≈", "at the edge"),
             "below": ("↓", "below"), "outside": ("✗", "outside: flagged"),
             "unknown": ("–", "not judged")}


def _plausibility_table(panel: Panel) -> str:
    """The checks of a panel, one row each, the verdicts marked (class ``verdict`` and the
    verdict's name)."""
    rows = []
    for c in panel.checks:
        mark, words = _VERDICTS[c.verdict]
        value = f"{c.value:.2f} {esc(c.unit)}" if is_num(c.value) else "–"
        verdict = (f'<span class="verdict {c.verdict}">{mark} {words}</span>'
                   + (f'<br><span class="why">{esc(c.comment)}</span>' if c.comment else ""))
        rows.append((esc(c.measure), value, esc(c.reference), verdict))
    return html_table(["check", "this run", "measured in real crowds", "verdict"], rows,
                      "plausibility")


def plausibility_html(panels: Sequence[tuple[str, Panel]]) -> str:
    """The plausibility panels of runs (label, panel; labelled if more than one): each
    run's preset, whether anything is flagged, the checks; then how they are made."""
    body = ""
    for label, panel in panels:
        bad, edge = panel.flagged, panel.at_edge
        if bad:
            verdict = (f'<p class="plaus-flag"><b>{len(bad)} check{"s" * (len(bad) > 1)} '
                       "outside what real crowds were measured to do</b>: "
                       + "; ".join(esc(c.measure) for c in bad) + ".</p>")
        else:
            near = "; ".join(esc(c.measure) for c in edge)
            verdict = ('<p class="plaus-ok">Nothing outside what real crowds were measured '
                       "to do" + (f"; at the edge (within the tolerance): {near}" if edge
                                  else "") + ".</p>")
        body += ((f"<h3>{esc(label)}</h3>" if len(panels) > 1 else "")
                 + f'<div class="plausibility" data-flagged="{len(bad)}">'
                 + f'<p class="preset">{esc(panel.preset)}</p>' + verdict
                 + _plausibility_table(panel) + "</div>")
    return body + "".join(f"<p>{esc(x)}</p>" for x in method_sentences())


_CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,Helvetica,Arial,sans-serif;
 margin:0;color:#1d1d1f;background:#fafafa;line-height:1.45}
main{max-width:1150px;margin:0 auto;padding:1.2em 1.5em 3em;background:#fff}
h1{font-size:1.6em;margin:.2em 0 .1em}h2{border-bottom:2px solid #e3e3e3;padding-bottom:.2em;
 margin-top:1.8em}h3{margin-top:1.4em}.sub{color:#666;margin-top:0}
.summary{background:#eef5fb;border-left:5px solid #1f77b4;padding:.6em 1em;font-size:1.08em}
.summary p{margin:.35em 0}
table{border-collapse:collapse;margin:.6em 0;font-size:.92em}
th,td{border:1px solid #ddd;padding:.25em .6em;text-align:left;vertical-align:top}
th{background:#f2f2f2}td .num{font-variant-numeric:tabular-nums}
img.plot,img.snap{max-width:100%;height:auto;display:block;margin:.5em 0}
.controls{display:flex;align-items:center;gap:.8em;margin:.4em 0}
.controls input{flex:1}.snap-label{min-width:6em;font-weight:600}
nav a{margin-right:1em}.na{color:#8a4b00;background:#fff6e5;padding:.4em .8em}
ul.warnings li{color:#8a4b00}ul.warnings li.none{color:#1d1d1f}
details{margin:.5em 0}summary{cursor:pointer;color:#1f5f99}
code{font-size:.9em}footer{color:#777;font-size:.85em;margin-top:3em}
.plaus-flag{background:#fdecea;border-left:5px solid #b00020;padding:.4em .8em}
.plaus-ok{background:#edf7ee;border-left:5px solid #1a7f37;padding:.4em .8em}
.verdict{font-weight:600;white-space:nowrap}.verdict.within{color:#1a7f37}
.verdict.outside{color:#b00020}.verdict.edge,.verdict.below{color:#8a4b00}
.verdict.unknown{color:#666}.why{color:#444;font-size:.92em}
"""


_JS = """
(function () {
  function setUp(box) {
    var data = JSON.parse(box.querySelector('script.snap-data').textContent);
    var img = box.querySelector('img.snap');
    var input = box.querySelector('input.slider');
    var label = box.querySelector('.snap-label');
    var button = box.querySelector('button.play');
    var timer = null;
    function show(i) {
      img.src = data.images[i];
      label.textContent = data.labels[i];
      input.value = String(i);
    }
    input.addEventListener('input', function () { show(parseInt(input.value, 10)); });
    button.addEventListener('click', function () {
      if (timer !== null) {
        clearInterval(timer); timer = null; button.innerHTML = '&#9654; play'; return;
      }
      button.innerHTML = '&#10074;&#10074; pause';
      timer = setInterval(function () {
        var i = parseInt(input.value, 10) + 1;
        if (i >= data.images.length) { i = 0; }
        show(i);
      }, 400);
    });
  }
  document.querySelectorAll('.snapshots').forEach(setUp);
})();
"""


class Page:
    def __init__(self, title: str) -> None:
        self.title = title
        self.parts: list[str] = []
        self.nav: list[tuple[str, str]] = []
        self._uid = 0

    def uid(self, prefix: str) -> str:
        self._uid += 1
        return f"{prefix}-{self._uid}"

    def section(self, anchor: str, title: str, body: str, level: int = 2) -> None:
        if level == 2:
            self.nav.append((anchor, title))
        self.parts.append(f'<section id="{anchor}"><h{level}>{esc(title)}</h{level}>'
                          f"{body}</section>")

    def add(self, text: str) -> None:
        self.parts.append(text)

    def html(self, subtitle: str, summary: str) -> str:
        nav = " ".join(f'<a href="#{a}">{esc(t)}</a>' for a, t in self.nav)
        stamp = _dt.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z")
        return (
            "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            '<meta name="viewport" content="width=device-width, initial-scale=1">'
            '<link rel="icon" href="data:,">'
            f"<title>{esc(self.title)}</title><style>{_CSS}</style></head><body><main>"
            f"<h1>{esc(self.title)}</h1><p class=\"sub\">{subtitle}</p>"
            f'<div class="summary" id="summary">{summary}</div>'
            f"<nav>{nav}</nav>" + "".join(self.parts)
            + f"<footer>Made by pedmesh {esc(__version__)} (<code>pedmesh report</code>) on "
            f"{esc(stamp)}. The page is self-contained: it loads nothing from anywhere."
            f"</footer></main><script>{_JS}</script></body></html>\n")
