"""Reading a tipgeo HTML report back in tests: its plotly figures (base64
typed arrays decoded), its link table and the external references of its
tags."""

from __future__ import annotations

import base64
import json
import re
from html.parser import HTMLParser

import numpy as np

__all__ = ["figures", "links", "external_refs", "decode"]

_DT = {"f4": "<f4", "f8": "<f8", "i1": "i1", "u1": "u1", "i2": "<i2", "u2": "<u2",
       "i4": "<i4", "u4": "<u4", "i8": "<i8", "u8": "<u8"}


def decode(v):
    """A plotly typed array ({dtype, bdata[, shape]}) as numpy; else as it is."""
    if isinstance(v, dict) and "bdata" in v:
        a = np.frombuffer(base64.b64decode(v["bdata"]), dtype=_DT[v["dtype"]])
        if "shape" in v:
            a = a.reshape([int(x) for x in str(v["shape"]).split(",")])
        return a
    return v


def _walk(o):
    if isinstance(o, dict):
        if "bdata" in o and "dtype" in o:
            return decode(o)
        return {k: _walk(v) for k, v in o.items()}
    if isinstance(o, list):
        return [_walk(v) for v in o]
    return o


def figures(text: str) -> dict[str, dict]:
    """{div id: figure dict} of every ``Plotly.newPlot`` in the page."""
    out = {}
    dec = json.JSONDecoder()
    for m in re.finditer(r"<script>\(function\(\)\{var f=", text):
        fig, end = dec.raw_decode(text, m.end())
        div = re.match(r';Plotly\.newPlot\("([^"]+)"', text[end:end + 200]).group(1)
        out[div] = _walk(fig)
    return out


def links(text: str) -> list[dict]:
    m = re.search(r'<script type="application/json" id="tg-links">(.*?)</script>', text, re.S)
    return json.loads(m.group(1))


class _Refs(HTMLParser):
    def __init__(self):
        super().__init__()
        self.refs = []

    def handle_starttag(self, tag, attrs):
        for k, v in attrs:
            if k in ("src", "href", "data", "action", "srcset", "poster") and v:
                self.refs.append((tag, k, v))


def external_refs(text: str) -> list[tuple[str, str, str]]:
    """(tag, attribute, value) of every attribute that loads something and
    is not a page-internal anchor (``#…``)."""
    p = _Refs()
    p.feed(text)
    return [r for r in p.refs if not r[2].startswith("#")]
