"""The planner page as one self-contained HTML file: plotly.js embedded once (as the report),
the grid of predictions as JSON, and ``planner.js`` (package data) that draws and designs."""
from __future__ import annotations

import html
import json
from importlib import resources
from pathlib import Path
from typing import Any

import plotly.io as pio
from plotly.offline import get_plotlyjs

from droptower.io.droptower_log import atomic_write
from droptower.planner.grid import planner_data
from droptower.report.figures import TEMPLATE
from droptower.report.page import STYLE
from droptower.rheology import Coupling
from droptower.rig.config import RigConfig
from droptower.errors import expects

PLANNER_STYLE = """
body{max-width:1400px}
.cols{display:grid;grid-template-columns:430px minmax(0,1fr);gap:18px;align-items:start}
fieldset{border:1px solid #ddd;margin:0 0 12px;padding:6px 10px 10px}legend{font-weight:600}
label{display:inline-block;min-width:110px}input[type=number]{width:90px}select{min-width:220px}
.row{margin:4px 0}#height-slider{width:300px;vertical-align:middle}
#conditions td,#conditions th{font-size:12px}
button{padding:4px 14px;font-size:14px}
.hint{color:#555;font-size:13px}
"""

#: How the page tells its reader to run a saved plan, in Python (the command line passes its own form).
RUN_HINT = 'droptower.run_campaign("runs/designed", doe="plan.toml")'


def page_html(data: dict[str, Any], run_hint: str = RUN_HINT) -> str:
    """The whole HTML document of the planner for ``data`` (:func:`droptower.planner.planner_data`)."""
    rig, preloads = data["rig"], ", ".join(f"{p:g}" for p in data["preloads_nm"])
    lo, hi = rig["drop_height_range_m"]
    title = f"droptower planner: rig {rig['name']}, coupling {data['coupling']}"
    script = resources.files("droptower.planner").joinpath("planner.js").read_text(encoding="utf-8")
    template = json.dumps(pio.templates[TEMPLATE].to_plotly_json())
    data_json = json.dumps(data, allow_nan=False).replace("</", "<\\/")
    body = f"""
<h1>{html.escape(title)}</h1>
<p class="hint">Predictions of <code>droptower plan</code> (free decay on the nonlinear coupling, impact law,
double-impact check, sensor ranges, twist limit) computed by the package on {len(data['heights_m'])} heights
{lo:g}–{hi:g} m per lever, drop mass and preload ({html.escape(preloads)} N·m), interpolated in log height.
The design is <code>droptower design</code>'s selection on the same candidates.</p>
<div class="cols"><div>
<fieldset><legend>One drop</legend>
<div class="row"><label for="lever">lever</label><select id="lever"></select></div>
<div class="row"><label for="mass">drop mass</label><select id="mass"></select></div>
<div class="row"><label for="preload">preload</label><select id="preload"></select></div>
<div class="row"><label for="height">height [m]</label><input id="height" type="number" step="0.001" value="0.5">
<input id="height-slider" type="range" min="0" max="1" step="0.001" aria-label="height (log scale)"></div>
<table class="facts" id="prediction"></table>
<p id="drop-problems"></p>
</fieldset>
<fieldset><legend>Design a campaign</legend>
<p class="hint">Drag a box on the plot, or type the target.</p>
<div class="row"><label for="a-lo">amplitude [deg]</label><input id="a-lo" type="number" step="any" value="0.3"> –
<input id="a-hi" type="number" step="any" value="3" aria-label="highest amplitude [deg]"></div>
<div class="row"><label for="f-lo">frequency [Hz]</label><input id="f-lo" type="number" step="any" value="22"> –
<input id="f-hi" type="number" step="any" value="50" aria-label="highest frequency [Hz]"></div>
<div class="row"><label for="repeats">repeats</label><input id="repeats" type="number" min="1" step="1"
value="{data['settings']['default_repeats']}"></div>
<div class="row"><label for="max-tests">max tests</label><input id="max-tests" type="number" min="1" step="1"
placeholder="none"></div>
<div class="row"><label for="file-name">plan file</label><input id="file-name" type="text" value="plan.toml">
<button id="download" type="button">Download plan TOML</button></div>
<p id="design-summary"></p><ul id="design-notes" class="hint"></ul>
</fieldset>
</div><div><div id="plane"></div>
<div class="scroll"><table class="plain" id="conditions"></table></div>
<p class="hint">Run it with <code>{html.escape(run_hint)}</code>.</p>
<pre id="toml"></pre></div></div>"""
    return (
        "<!doctype html><html lang='en'><head><meta charset='utf-8'>"
        "<meta name='viewport' content='width=device-width, initial-scale=1'>"
        f"<title>{html.escape(title)}</title><style>{STYLE}{PLANNER_STYLE}</style>"
        f"<script type='text/javascript'>{get_plotlyjs()}</script></head><body>{body}"
        f"<script type='application/json' id='planner-data'>{data_json}</script>"
        f"<script type='application/json' id='plotly-template'>{template}</script>"
        f"<script>{script}</script></body></html>\n")


@expects(rig="droptower.rig.config.RigConfig", coupling="droptower.rheology.coupling.Coupling")
def write_planner(rig: RigConfig, coupling: Coupling, preloads_nm: tuple[float, ...], out: str | Path,
                  run_hint: str = RUN_HINT) -> Path:
    """Predict the grid for ``rig`` and ``coupling`` at ``preloads_nm`` (N*m) and write the page to ``out``;
    ``run_hint``: how the page tells its reader to run a saved plan (the command line gives its own)."""
    text = page_html(planner_data(rig, coupling, preloads_nm), run_hint)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(out, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))
    return out
