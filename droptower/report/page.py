"""The report as one self-contained HTML file: plotly.js and the table library (itables'
DataTables bundle) embedded once, every figure's data inline, no server, no network, no
absolute paths. Sections: summary, failures and flags (with their reasons), the map
(coefficients, fit and cross-validated errors, figure), the sortable per-test table, and the
decay fit of the test chosen in the table (its name links there), then any extra sections.
A report of many tests keeps the decay figures in side files beside the page
(``report_files/fits_0000.js``, 100 tests each), loaded when a test is chosen: the page stays
small enough to open at once, and it still needs no server or network.

The only JavaScript written here is the glue that draws the chosen test's stored figure.
"""
from __future__ import annotations

import html
import json
import math
from typing import Any

import pandas as pd
import plotly.io as pio
from itables import to_html_datatable
from itables.javascript import generate_init_offline_itables_html
from itables.options import dt_bundle
from plotly.offline import get_plotlyjs

from droptower.maps import MapFit
from droptower.report.figures import TEMPLATE

STYLE = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;font-size:14px;line-height:1.4;color:#222;
     max-width:1240px;margin:0 auto;padding:0 16px 40px}
h1{font-size:22px;margin:18px 0 4px}h2{font-size:18px;margin:28px 0 8px;border-bottom:1px solid #ddd;padding-bottom:3px}
nav a{margin-right:14px}
table.facts,table.plain{border-collapse:collapse;margin:6px 0}
table.facts th,table.facts td,table.plain th,table.plain td{border:1px solid #ddd;padding:3px 8px;text-align:left;
     vertical-align:top}
table.plain td.num{text-align:right;font-variant-numeric:tabular-nums}
table.data{border-collapse:collapse;font-size:13px}table.data td,table.data th{border:1px solid #ddd;padding:2px 6px;
     text-align:right}
.ok{color:#2a7d2a}.bad{color:#b00020;font-weight:600}.warn{color:#a05a00}
.scroll{overflow-x:auto}
pre{background:#f6f6f6;padding:.6em;white-space:pre-wrap;word-break:break-word}
img{max-width:100%}
#decay-note{color:#555}
"""

GLUE = """
const FITS = JSON.parse(document.getElementById("decay-data").textContent);
const FILES = JSON.parse(document.getElementById("decay-files").textContent);
const TEMPLATE = JSON.parse(document.getElementById("plotly-template").textContent);
const LOADING = {};
function droptowerFits(more) { Object.assign(FITS, more); }  // what a side file of figures calls
function showFit(scroll) {
  let name = decodeURIComponent(location.hash.replace(/^#fit-/, ""));
  if (!(name in FITS) && !(name in FILES)) { name = Object.keys(FITS).concat(Object.keys(FILES))[0]; scroll = false; }
  if (name === undefined) return;
  document.getElementById("decay-title").textContent = name;
  if (!(name in FITS)) {  // its figure is in a side file: load that once, then draw
    const src = FILES[name];
    document.getElementById("decay-message").textContent = "loading " + src;
    if (!LOADING[src]) {
      LOADING[src] = true;
      const script = document.createElement("script");
      script.src = src;
      script.onload = () => showFit(scroll);
      script.onerror = () => { document.getElementById("decay-message").textContent = "No plot: cannot read " + src; };
      document.head.appendChild(script);
    }
    return;
  }
  const fig = FITS[name];
  document.getElementById("decay-message").textContent = typeof fig === "string" ? "No plot: " + fig : "";
  if (typeof fig === "string") {
    Plotly.purge("decay");
  } else {
    fig.layout.template = TEMPLATE;
    Plotly.react("decay", fig.data, fig.layout, {responsive: true});
  }
  if (scroll) document.getElementById("fits").scrollIntoView();
}
window.addEventListener("hashchange", () => showFit(true));
showFit(location.hash.startsWith("#fit-"));
"""


def fit_link(name: str) -> str:
    """A link that shows the test's decay fit (the glue reads the name from the URL's hash)."""
    return f"<a href='#fit-{html.escape(name, quote=True)}'>{html.escape(name)}</a>"


def facts_table(facts: list[tuple[str, str]]) -> str:
    rows = "".join(f"<tr><th>{html.escape(k)}</th><td>{html.escape(v)}</td></tr>" for k, v in facts)
    return f"<table class='facts'>{rows}</table>"


def plain_table(table: pd.DataFrame, html_columns: tuple[str, ...] = ()) -> str:
    """A small static table; numbers to 4 significant digits, ``html_columns`` as given."""
    head = "".join(f"<th>{html.escape(str(c))}</th>" for c in table.columns)
    body = []
    for _, row in table.iterrows():
        cells = []
        for c, v in row.items():
            if c in html_columns:
                cells.append(f"<td>{v}</td>")
            elif isinstance(v, float):
                cells.append(f"<td class='num'>{'' if math.isnan(v) else f'{v:.4g}'}</td>")
            else:
                cells.append(f"<td>{html.escape(str(v))}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    return f"<div class='scroll'><table class='plain'><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table></div>"


def map_section(fit: MapFit | None, error: str | None, figure: Any | None) -> str:
    """Form, fit and cross-validated errors, the coefficient table and the map figure."""
    if fit is None:
        return f"<p class='bad'>No map: {html.escape(error or 'no usable tests')}</p>"
    s = fit.stats
    errors = pd.DataFrame({
        "quantity": ["stiffness", "d = E_diss/E_el (Rapp et al. 2022)"],
        "RMS error of the fit [%]": [s.stiffness_rms_error_pct, s.damping_ratio_rms_error_pct],
        "cross-validated RMS error [%]": [s.stiffness_cv_rms_error_pct, s.damping_ratio_cv_rms_error_pct],
        "max error of the fit [%]": [s.stiffness_max_error_pct, s.damping_ratio_max_error_pct],
    }).astype(object).where(lambda t: t.notna(), float("nan"))
    coefficients = fit.coefficient_table()
    coefficients["note"] = ["at its bound" if b else "not unique" if u else
                            "not identifiable" if not math.isfinite(std) else
                            "poorly identified (> 50 %)" if std > 0.5 * abs(v) else ""
                            for b, u, std, v in zip(coefficients["at_bound"], coefficients["not_unique"],
                                                    coefficients["std"].fillna(math.inf), coefficients["value"])]
    coefficients = coefficients.drop(columns=["at_bound", "not_unique"])
    eq = fit.form.equations()
    r = fit.range
    parts = [
        f"<p>Form <b>{html.escape(fit.form.name)}</b> fitted to {s.n_tests} tests ({len(fit.excluded)} excluded, "
        f"listed above); measured range {r.amplitude_deg_min:.3g}–{r.amplitude_deg_max:.3g} deg, "
        f"{r.frequency_hz_min:.4g}–{r.frequency_hz_max:.4g} Hz. Cross-validation: "
        f"{html.escape(fit.cross_validation or 'none')} (each test predicted by the map fitted without it).</p>",
        f"<p>c(a, f) = {html.escape(eq['stiffness_nm_per_deg'])} [N·m/deg]<br>d(a, f) = "
        f"{html.escape(eq['damping_ratio'])}; a: amplitude [deg], f: frequency [Hz]</p>",
        plain_table(errors),
        plain_table(coefficients),
    ]
    if fit.fixtures or fit.temperature_range_c:
        parts.insert(1, "<p>" + "; ".join(
            ([f"fixtures {html.escape(', '.join(fit.fixtures))}"] if fit.fixtures else [])
            + ([f"temperature {fit.temperature_range_c[0]:.1f}–{fit.temperature_range_c[1]:.1f} °C"]
               if fit.temperature_range_c else [])) + ".</p>")
    if fit.coverage:  # what the map does not cover, said where the map is
        items = "".join(f"<li>{html.escape(line)}</li>" for line in fit.coverage)
        parts.insert(1, f"<div id='not-covered' class='warn'><p>Not covered by the map:</p><ul>{items}</ul></div>")
    if figure is not None:
        parts.append(pio.to_html(figure, include_plotlyjs=False, full_html=False, default_height="420px",
                                 config={"responsive": True, "displaylogo": False}))
    return "".join(parts)


def tests_table(table: pd.DataFrame) -> str:
    """The sortable, searchable per-test table (itables/DataTables, offline); the ``test``
    column holds links to the decay fits. A click anywhere on a column's title sorts (itables'
    default keeps the title's text selectable and sorts only on the small arrow). Rows are made
    when their page is shown (DataTables' deferRender): a table of 4 500 tests opens with 25.
    The numbers, already rounded to their shown digits, go to the page as numbers: formatting
    them in Python took seconds for 4 500 tests."""
    return to_html_datatable(table, connected=False, allow_html=True, classes="display compact", lengthMenu=[
        25, 100, 500], pageLength=25, order=[], showIndex=False, table_id="tests-table", maxBytes=0, scrollX=True,
        text_in_header_can_be_selected=False, deferRender=True, format_floats_in_python=False)


def page(title: str, facts: list[tuple[str, str]], problems: str, map_html: str, tests_html: str,
         fits: dict[str, Any], extra_sections: list[tuple[str, str]], fit_files: dict[str, str] | None = None) -> str:
    """The whole HTML document. fits: test name -> its decay figure (or why it has none), drawn
    from the page; fit_files: test name -> the side file (a relative URL) holding its figure,
    loaded when the test is chosen (a report of thousands of tests)."""
    template = pio.templates[TEMPLATE].to_plotly_json()
    fits_json = pio.to_json(fits, validate=False).replace("</", "<\\/")
    files_json = json.dumps(fit_files or {}).replace("</", "<\\/")
    sections = [("summary", "Summary", facts_table(facts)), ("problems", "Failures and flags", problems),
                ("map", "Characteristic map", map_html), ("tests", "Tests", tests_html),
                ("fits", "Decay fit", "<p id='decay-note'>Measured angle and torque with the fitted decay "
                 "(Rapp et al. 2022, eq. 13, 17): solid in the fit window (shaded), dashed beyond. Choose a test by its "
                 "name in the table.</p><h3 id='decay-title'></h3><p id='decay-message' class='warn'></p><div id='decay'></div>")]
    sections += [(f"extra{i}", heading, body) for i, (heading, body) in enumerate(extra_sections)]
    nav = "".join(f"<a href='#{sid}'>{html.escape(heading)}</a>" for sid, heading, _ in sections)
    body = "".join(f"<section id='{sid}'><h2>{html.escape(heading)}</h2>{content}</section>"
                   for sid, heading, content in sections)
    return (
        "<!doctype html><html lang='en'><head><meta charset='utf-8'>"
        "<meta name='viewport' content='width=device-width, initial-scale=1'>"
        f"<title>{html.escape(title)}</title><style>{STYLE}</style>"
        f"<script type='text/javascript'>{get_plotlyjs()}</script>"
        f"{generate_init_offline_itables_html(dt_bundle)}</head><body>"
        f"<h1>{html.escape(title)}</h1><nav>{nav}</nav>{body}"
        f"<script type='application/json' id='decay-data'>{fits_json}</script>"
        f"<script type='application/json' id='decay-files'>{files_json}</script>"
        f"<script type='application/json' id='plotly-template'>{json.dumps(template)}</script>"
        f"<script>{GLUE}</script></body></html>\n")
