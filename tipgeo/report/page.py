"""One self-contained HTML page: sections of plotly figures, tables and text,
with plotly.js and the page's own script inlined (no network request: no
``src``/``href`` to any address, no font or map tiles).

Units are the report's (mm, degrees, µm), always named in axis titles and
table headers; frames are named in each section's note.
"""

from __future__ import annotations

import html
import json
import math
from dataclasses import dataclass, field
from typing import Any

__all__ = ["Page", "Section", "PLOT_CONFIG"]

#: plotly's config for every figure: no logo, no link to plotly's cloud, a
#: PNG button that writes locally.
PLOT_CONFIG = {"displaylogo": False, "showLink": False, "responsive": True,
               "toImageButtonOptions": {"format": "png", "scale": 2}}

_CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:0;color:#222;
background:#fafafa}
header{background:#1f3b57;color:#fff;padding:14px 24px}
header h1{margin:0;font-size:20px} header p{margin:4px 0 0;font-size:13px;opacity:.85}
nav{padding:6px 24px;background:#e9eef3;font-size:13px} nav a{margin-right:14px;color:#1f3b57}
section{background:#fff;margin:16px 24px;padding:12px 18px;border:1px solid #dde3ea;
border-radius:6px}
section h2{font-size:17px;margin:4px 0 6px} p.note{font-size:13px;color:#555;margin:4px 0 10px}
table{border-collapse:collapse;font-size:12.5px;margin:6px 0 14px}
th,td{border:1px solid #d5dbe1;padding:3px 8px;text-align:right}
th{background:#eef2f6} td.l,th.l{text-align:left} caption{text-align:left;font-weight:600;
padding:4px 0;font-size:13px}
.ok{color:#1a7f37;font-weight:600} .bad{color:#c62828;font-weight:600}
.tg-plot{width:100%} .row{display:flex;gap:12px;flex-wrap:wrap} .row>div{flex:1 1 480px}
.tg-controls{font-size:13px;margin:4px 0 8px;display:flex;gap:10px;align-items:center}
.tg-controls input[type=range]{flex:1}
.tg-readout{font-size:13px;color:#333;min-height:1.3em}
details{margin:6px 0 14px;font-size:13px} summary{cursor:pointer;font-weight:600}
"""


def _json(obj: Any) -> str:
    """JSON safe inside a <script> element."""
    return (json.dumps(obj, separators=(",", ":"), allow_nan=False)
            .replace("</", "<\\/").replace("<!--", "<\\!--"))


def _cell(v: Any) -> str:
    if v is None:
        return "–"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        if not math.isfinite(v):
            return "–"
        a = abs(v)
        return f"{v:.4g}" if (a >= 1e5 or (0 < a < 1e-3)) else f"{v:.6g}"
    if isinstance(v, (list, tuple)):
        return ", ".join(_cell(x) for x in v)
    return str(v)


@dataclass
class Section:
    """A part of the page: a heading, a note and blocks in order."""

    title: str
    anchor: str
    note: str = ""
    blocks: list[str] = field(default_factory=list)
    page: Page | None = field(default=None, repr=False)

    def figure(self, fig: Any, *, height: int = 520, name: str = "plot") -> str:
        """Add a plotly figure; returns its div id (the page's script finds it
        by that id)."""
        if self.page is None:
            raise ValueError(f"section {self.title!r} belongs to no page; make it with "
                             "Page.section")
        div = self.page._id(name)
        spec = fig.to_plotly_json()
        layout = spec.get("layout", {})
        layout.setdefault("height", height)
        payload = fig.to_json().replace("</", "<\\/")  # numpy arrays: base64 typed arrays
        self.blocks.append(
            f'<div id="{div}" class="tg-plot" data-kind="{html.escape(name)}" '
            f'style="height:{int(layout["height"])}px"></div>\n'
            f'<script>(function(){{var f={payload};'
            f'Plotly.newPlot("{div}",f.data,f.layout,{_json(PLOT_CONFIG)});}})();</script>')
        return div

    def table(self, columns: list[str], rows: list[list[Any]], *, caption: str = "",
              left: int = 1, folded: bool = False) -> None:
        """Add a table; ``columns`` carry their units (``"λ (deg)"``); the
        first ``left`` columns are text, left-aligned; ``folded``: behind a
        click (its caption shown)."""
        head = "".join(f'<th class="{"l" if k < left else ""}">{html.escape(c)}</th>'
                       for k, c in enumerate(columns))
        body = "".join(
            "<tr>" + "".join(f'<td class="{"l" if k < left else ""}">{html.escape(_cell(v))}'
                             "</td>" for k, v in enumerate(r)) + "</tr>" for r in rows)
        cap = f"<caption>{html.escape(caption)}</caption>" if caption and not folded else ""
        t = (f'<table class="tg-table">{cap}<thead><tr>{head}</tr></thead>'
             f"<tbody>{body}</tbody></table>")
        if folded:
            t = (f"<details><summary>{html.escape(caption or 'table')} ({len(rows)} rows)"
                 f"</summary>{t}</details>")
        self.blocks.append(t)

    def text(self, s: str, cls: str = "note") -> None:
        """Add a paragraph (escaped)."""
        self.blocks.append(f'<p class="{cls}">{html.escape(s)}</p>')

    def verdict(self, v: dict[str, Any] | None) -> None:
        """Add a verdict dict (:meth:`tipgeo.verdict.Verdict.to_dict`): the
        line and its checks as a table."""
        if not v:
            return
        ok = bool(v.get("ok"))
        self.blocks.append(f'<p class="{"ok" if ok else "bad"} tg-verdict">'
                           f'{"PASS" if ok else "FAIL"} {html.escape(str(v.get("subject", "")))}'
                           + (": " + html.escape("; ".join(v.get("reasons") or []))
                              if not ok else "") + "</p>")
        rows = [[c.get("name"), "pass" if c.get("ok") else "FAIL", c.get("value"),
                 c.get("rule") or "", c.get("reason") or ""] for c in v.get("checks") or []]
        if rows:
            self.table(["check", "result", "value", "rule", "reason"], rows, caption="verdict",
                       left=5)
        skipped = v.get("not_judged") or []
        if skipped:
            self.text("Not judged (the input does not show enough of it; the verdict holds "
                      "for the rest only): " + "; ".join(str(x) for x in skipped) + ".")

    def raw(self, trusted_html: str) -> None:
        """Add markup built by this package (never from user strings)."""
        self.blocks.append(trusted_html)


class Page:
    """The report page: a title, sections and the data its script links."""

    def __init__(self, title: str, subtitle: str = "") -> None:
        self.title, self.subtitle = title, subtitle
        self.sections: list[Section] = []
        self.links: list[dict[str, Any]] = []  # what the page script wires (see _script.js)
        self._n = 0

    def _id(self, name: str) -> str:
        self._n += 1
        safe = "".join(ch if ch.isalnum() else "-" for ch in name)[:24]
        return f"tg-{safe}-{self._n}"

    def section(self, title: str, note: str = "") -> Section:
        s = Section(title, self._id("sec"), note, page=self)
        self.sections.append(s)
        return s

    def link(self, **kw: Any) -> None:
        """Record an interaction for the page script (hover, slider, pick)."""
        self.links.append(kw)

    def render(self) -> str:
        """The page as one HTML string (plotly.js inlined)."""
        from importlib.resources import files

        from plotly.offline import get_plotlyjs

        script = files("tipgeo.report").joinpath("page.js").read_text(encoding="utf-8")
        nav = "".join(f'<a href="#{s.anchor}">{html.escape(s.title)}</a>' for s in self.sections)
        body = "".join(
            f'<section id="{s.anchor}"><h2>{html.escape(s.title)}</h2>'
            + (f'<p class="note">{html.escape(s.note)}</p>' if s.note else "")
            + "\n".join(s.blocks) + "</section>\n" for s in self.sections)
        plotly_js = get_plotlyjs().replace("</script", "<\\/script")
        return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
                "<meta name=\"viewport\" content=\"width=device-width,initial-scale=1\">"
                f"<title>{html.escape(self.title)}</title><style>{_CSS}</style>"
                f"<script>{plotly_js}</script></head><body>"
                f"<header><h1>{html.escape(self.title)}</h1>"
                f"<p>{html.escape(self.subtitle)}</p></header><nav>{nav}</nav>\n{body}"
                f'<script type="application/json" id="tg-links">{_json(self.links)}</script>'
                f"<script>{script}</script></body></html>\n")
