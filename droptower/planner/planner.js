// The droptower planner page: predictions of one drop and the design of a campaign, offline.
//
// The predictions are droptower.rig.predictions.plan's, computed by the package on a grid of
// heights (the JSON in #planner-data) and interpolated here linearly in log height. The design
// repeats droptower/design/choose.py step by step (_levels, _lever_drops, _choose and the
// --max-tests loop of design_campaign) on the same candidates, so the page chooses the drops
// `droptower design` chooses; the plan TOML is outputs.doe_document as tomli_w writes it.
"use strict";

const D = JSON.parse(document.getElementById("planner-data").textContent);
const S = D.settings;
const NM = D.masses_kg.length, NP = D.preloads_nm.length, NH = D.heights_m.length;
const LOG_H = D.heights_m.map(Math.log);

// ---------------------------------------------------------------- numbers as Python prints them
// format(x, ".{p}g")
function fmtG(x, p = 6) {
  if (!Number.isFinite(x)) return String(x);
  if (x === 0) return "0";
  const [mant, exp] = x.toExponential(p - 1).split("e");
  const e = Number(exp);
  const strip = (s) => (s.includes(".") ? s.replace(/0+$/, "").replace(/\.$/, "") : s);
  if (e >= -4 && e < p) return strip(x.toFixed(Math.max(0, p - 1 - e)));
  return `${strip(mant)}e${e < 0 ? "-" : "+"}${String(Math.abs(e)).padStart(2, "0")}`;
}
// repr(float), as tomli_w writes a float
function pyFloat(x) {
  if (Number.isInteger(x) && Math.abs(x) < 1e16) return x.toFixed(1);
  if (Math.abs(x) >= 1e-4 && Math.abs(x) < 1e16) return String(x);
  const [mant, exp] = x.toExponential().split("e");
  const e = Number(exp);
  return `${mant}e${e < 0 ? "-" : "+"}${String(Math.abs(e)).padStart(2, "0")}`;
}
// round(x, digits) for x >= 0: the decimal nearest to the exact binary value; exact ties (x * 16
// an odd integer, the only ones at 3 digits) half to even as Python
function pyRound(x, digits) {
  const scaled = x * 10 ** digits;
  if (digits === 3 && Number.isInteger(x * 16) && (x * 16) % 2 === 1) {
    const lo = Math.floor(scaled);
    return (lo % 2 === 0 ? lo : lo + 1) / 10 ** digits;
  }
  return Number(x.toFixed(digits));
}

// ---------------------------------------------------------------- the grid: one drop
function gridIndex(lever, mass, preload, k) { return ((lever * NM + mass) * NP + preload) * NH + k; }

// Every predicted quantity at height h (m), linear in log height between the grid's heights;
// a double impact where both neighbouring grid heights have one (else the clearance tells).
function predict(lever, mass, preload, h) {
  const u = Math.log(h);
  let k = 0;
  while (k < NH - 2 && LOG_H[k + 1] < u) k++;
  const w = Math.min(1, Math.max(0, (u - LOG_H[k]) / (LOG_H[k + 1] - LOG_H[k])));
  const i = gridIndex(lever, mass, preload, k);
  const out = {};
  for (const q of Object.keys(D.grid)) {
    const a = D.grid[q][i], b = D.grid[q][i + 1];
    if (typeof a === "boolean") out[q] = a && b;
    else out[q] = a === null || b === null ? NaN : a + w * (b - a);
  }
  return out;
}

// What limits this prediction hits (droptower.rig.predictions's warnings and the design's margin)
function problems(p) {
  const r = D.rig, out = [];
  if (Number.isNaN(p.frequency_hz)) out.push("no complete oscillation");
  if (p.max_twist_deg > r.coupling_limit_deg) out.push(`twist ${p.max_twist_deg.toFixed(1)} deg > coupling limit ${fmtG(r.coupling_limit_deg)} deg`);
  if (p.peak_torque_nm > r.torque_range_nm) out.push(`torque ${p.peak_torque_nm.toFixed(0)} N*m > sensor range ${fmtG(r.torque_range_nm)} N*m`);
  if (p.impact_force_peak_n > r.impact_force_range_n) out.push(`impact force ${p.impact_force_peak_n.toFixed(0)} N > sensor range ${fmtG(r.impact_force_range_n)} N`);
  if (p.samples_per_period < S.min_samples_per_period) out.push(`only ${p.samples_per_period.toFixed(0)} samples per period`);
  if (p.double_impact) out.push("double impact");
  else if (p.min_clearance_mm < S.min_clearance_mm) out.push(`double-impact clearance ${fmtG(p.min_clearance_mm, 2)} mm < ${fmtG(S.min_clearance_mm)} mm`);
  return out;
}

// ---------------------------------------------------------------- coverage.py
function linspace(a, b, n) {  // numpy.linspace
  if (n === 1) return [a];
  const step = (b - a) / (n - 1);
  return Array.from({length: n}, (_, i) => (i === n - 1 ? b : i * step + a));
}

// Target.grid(): (log10 amplitude_deg, frequency_hz) points, amplitude-major
function targetGrid(t) {
  const n = S.target_grid_points;
  const a = linspace(Math.log10(t.amplitude_deg[0]), Math.log10(t.amplitude_deg[1]), n);
  const f = linspace(t.frequency_hz[0], t.frequency_hz[1], n);
  return a.flatMap((x) => f.map((y) => [x, y]));
}

// in_hull: queries in the convex hull of points (both axes scaled to unit span, 1e-9 slack);
// fewer than three points or points on a line: only queries on the points themselves
function inHull(points, queries, relTol = 1e-9) {
  points = points.filter((p) => Number.isFinite(p[0]) && Number.isFinite(p[1]));
  if (!points.length) return queries.map(() => false);
  const lo = [0, 1].map((d) => Math.min(...points.map((p) => p[d])));
  const span = [0, 1].map((d) => Math.max(...points.map((p) => p[d])) - lo[d] || 1);
  const scale = (p) => [(p[0] - lo[0]) / span[0], (p[1] - lo[1]) / span[1]];
  const P = points.map(scale), Q = queries.map(scale);
  const hull = P.length >= 3 ? convexHull(P) : [];
  if (hull.length < 3) return Q.map((q) => P.some((p) => Math.hypot(q[0] - p[0], q[1] - p[1]) <= relTol));
  const edges = hull.map((a, i) => {  // outward unit normal n and offset c: n.x + c <= 0 inside
    const b = hull[(i + 1) % hull.length], len = Math.hypot(b[0] - a[0], b[1] - a[1]);
    const n = [(b[1] - a[1]) / len, -(b[0] - a[0]) / len];
    return [n[0], n[1], -(n[0] * a[0] + n[1] * a[1])];
  });
  return Q.map((q) => edges.every(([nx, ny, c]) => nx * q[0] + ny * q[1] + c <= relTol));
}

// Andrew's monotone chain, counter-clockwise, no collinear vertices
function convexHull(P) {
  const pts = [...P].sort((a, b) => a[0] - b[0] || a[1] - b[1]);
  const cross = (o, a, b) => (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
  const half = (list) => {
    const h = [];
    for (const p of list) {
      while (h.length >= 2 && cross(h[h.length - 2], h[h.length - 1], p) <= 0) h.pop();
      h.push(p);
    }
    h.pop();
    return h;
  };
  return [...half(pts), ...half([...pts].reverse())];
}

function count(mask) { return mask.filter(Boolean).length; }
function fraction(mask) { return mask.length ? count(mask) / mask.length : 0; }

// ---------------------------------------------------------------- choose.py
const C = D.candidates;
const CANDS = C.inertia_kgm2.map((j, i) => ({j, m: C.drop_mass_kg[i], lh: C.log10_height_m[i],
                                             la: C.log10_amplitude_deg[i], f: C.frequency_hz[i]}));
const LEVERS = [...new Set(C.inertia_kgm2)].sort((a, b) => a - b);

function levels(t, step) {
  const lo = Math.log10(t.amplitude_deg[0]) - S.edge_margin_decades;
  const hi = Math.log10(t.amplitude_deg[1]) + S.edge_margin_decades;
  return hi > lo ? linspace(lo, hi, Math.max(2, Math.ceil((hi - lo) / step) + 1)) : [lo];
}

function interp(x, xp, fp) {  // numpy.interp
  if (x <= xp[0]) return fp[0];
  if (x >= xp[xp.length - 1]) return fp[fp.length - 1];
  let j = 0;
  while (xp[j + 1] <= x) j++;
  return ((fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])) * (x - xp[j]) + fp[j];
}

// One lever's drops per amplitude level: {j, m, h, la, f}
function leverDrops(rows, lvls) {
  const runs = [...new Set(rows.map((r) => r.m))].sort((a, b) => a - b).map((m) => {
    const g = rows.filter((r) => r.m === m).sort((a, b) => a.la - b.la);
    return {m, la: g.map((r) => r.la), lh: g.map((r) => r.lh), f: g.map((r) => r.f)};
  });
  const drops = new Map();
  for (const level of lvls) {
    let best = null;
    for (const run of runs) {
      const a = Math.min(Math.max(level, run.la[0]), run.la[run.la.length - 1]);
      if (best === null || Math.abs(a - level) < best.dist - 1e-12) {
        best = {dist: Math.abs(a - level), m: run.m, a, lh: interp(a, run.la, run.lh), f: interp(a, run.la, run.f)};
      }
    }
    drops.set(best.a.toFixed(6), {j: rows[0].j, m: best.m, h: 10 ** best.lh, la: best.a, f: best.f});
  }
  return [...drops.values()];
}

function roundHeight(h) {
  const [lo, hi] = D.rig.drop_height_range_m, res = S.height_resolution_m;
  return Math.min(Math.max(pyRound(Math.round(h / res) * res, 6), lo), hi);
}

function combinations(items, k) {
  if (k === 0) return [[]];
  return items.flatMap((x, i) => combinations(items.slice(i + 1), k - 1).map((rest) => [x, ...rest]));
}

function median(values) {
  const v = [...values].sort((a, b) => a - b), n = v.length;
  return n % 2 ? v[(n - 1) / 2] : (v[n / 2 - 1] + v[n / 2]) / 2;
}

// The designed drops [{j, m, h}] before the final prediction (choose._choose)
function chooseDrops(t, step) {
  const grid = targetGrid(t);
  const all = CANDS.map((c) => [c.la, c.f]);
  const reachMask = inHull(all, grid);
  const reach = grid.filter((_, i) => reachMask[i]);
  const lvls = levels(t, step);
  const perLever = new Map(LEVERS.map((j) => [j, leverDrops(CANDS.filter((c) => c.j === j), lvls)]));
  const pointsOf = (drops) => drops.map((d) => [d.la, d.f]);
  const coverage = (drops) => (reach.length ? fraction(inHull(pointsOf(drops), reach)) : 0);

  let best = null;  // key (rounded coverage, fewest drops), compared as Python compares tuples
  for (let k = 1; k <= LEVERS.length; k++) {
    for (const subset of combinations(LEVERS, k)) {
      const drops = subset.flatMap((j) => perLever.get(j));
      const key = [pyRound(coverage(drops), 3), -drops.length];
      if (best === null || key[0] > best.key[0] || (key[0] === best.key[0] && key[1] > best.key[1])) best = {key, subset};
    }
  }
  const subset = [...best.subset];
  // a frequency span wants at least three frequency levels: levers crossing the band, nearest its middle first
  const [fLo, fHi] = t.frequency_hz;
  const mid = 0.5 * (fLo + fHi);
  const medianF = new Map(LEVERS.map((j) => [j, median(CANDS.filter((c) => c.j === j).map((c) => c.f))]));
  const inBand = LEVERS.filter((j) => CANDS.some((c) => c.j === j && c.f >= fLo && c.f <= fHi) && !subset.includes(j));
  for (const j of inBand.sort((a, b) => Math.abs(medianF.get(a) - mid) - Math.abs(medianF.get(b) - mid))) {
    if (fHi === fLo || subset.length >= 3) break;
    subset.push(j);
  }
  const drops = [...subset].sort((a, b) => a - b).flatMap((j) => perLever.get(j));
  // single candidate drops where the hull still misses reachable target points
  while (reach.length) {
    const pts = pointsOf(drops);
    const covered = inHull(pts, reach);
    const missing = reach.filter((_, i) => !covered[i]);
    if (!missing.length) break;
    const gains = CANDS.map((c) => count(inHull([...pts, [c.la, c.f]], missing)));
    const top = Math.max(...gains);
    if (top === 0) break;
    const c = CANDS[gains.indexOf(top)];
    drops.push({j: c.j, m: c.m, h: 10 ** c.lh, la: c.la, f: c.f});
  }
  return drops.map((d) => ({j: d.j, m: d.m, h: roundHeight(d.h)}));
}

// choose._unreachable: one sentence per part of the target the rig cannot reach, and why
function unreachable(t) {
  const grid = targetGrid(t), n = S.target_grid_points;
  const all = CANDS.map((c) => [c.la, c.f]);
  const inside = inHull(all, grid);
  if (!inside.some(Boolean)) return [];
  const amps = Array.from({length: n}, (_, i) => 10 ** grid[i * n][0]);
  const freqs = Array.from({length: n}, (_, k) => grid[k][1]);
  const [fLo, fHi] = t.frequency_hz, out = [];
  const byMax = (pick, sign) => LEVERS.reduce((best, j) => {  // first lever with the extreme frequency
    const v = sign * pick(CANDS.filter((c) => c.j === j).map((c) => c.f));
    return best === null || v > best.v ? {j, v} : best;
  }, null).j;
  const name = (j) => D.levers.find((l) => l.inertia_kgm2 === j).case;
  const sides = [["highest", fHi, byMax((f) => Math.max(...f), 1), "lightest"],
                 ["lowest", fLo, byMax((f) => Math.min(...f), -1), "heaviest"]];
  for (const [side, bound, lever, word] of sides) {
    // per amplitude row: null (nothing reachable), false (the bound is reached) or the edge reached
    const bands = amps.map((a, i) => {
      const reach = freqs.filter((_, k) => inside[i * n + k]);
      if (!reach.length) return [a, null];
      const edge = side === "highest" ? Math.max(...reach) : Math.min(...reach);
      const missing = side === "highest" ? edge < bound - 1e-9 : edge > bound + 1e-9;
      return [a, missing ? edge : false];
    });
    const runs = [];
    bands.forEach((b, i) => {
      if (b[1] === false) return;
      if (i > 0 && bands[i - 1][1] !== false) runs[runs.length - 1].push(b);
      else runs.push([b]);
    });
    for (const run of runs) {
      const a0 = run[0][0], a1 = run[run.length - 1][0];
      const edges = run.map((b) => b[1]).filter((e) => e !== null);
      const ampText = a1 > a0 ? `${fmtG(a0, 2)}-${fmtG(a1, 2)} deg` : `${fmtG(a0, 2)} deg`;
      if (!edges.length) {
        out.push(`at ${ampText} no drop of the rig lands in ${fmtG(fLo)}-${fmtG(fHi)} Hz`);
        continue;
      }
      const worst = side === "highest" ? Math.max(...edges) : Math.min(...edges);
      out.push(`at ${ampText} the ${side} frequency reachable is ${fmtG(worst, 3)} Hz: the ${word} lever, ${name(lever)}`);
    }
  }
  const reachA = CANDS.map((c) => 10 ** c.la);
  const [aMin, aMax] = [Math.min(...reachA), Math.max(...reachA)];
  if (t.amplitude_deg[1] > aMax) out.push(`above ${fmtG(aMax, 3)} deg no drop is possible without hitting a limit of rig ` +
                                          `${D.rig.name} (double impact, twist, sensor ranges or drop height)`);
  if (t.amplitude_deg[0] < aMin) out.push(`below ${fmtG(aMin, 3)} deg no drop is possible: the lowest drop height ` +
                                          `${fmtG(D.rig.drop_height_range_m[0])} m gives more`);
  return out;
}

function unique(drops) {  // sorted(set(drops))
  const seen = new Map(drops.map((d) => [`${d.j}|${d.m}|${d.h}`, d]));
  return [...seen.values()].sort((a, b) => a.j - b.j || a.m - b.m || a.h - b.h);
}

// design_campaign: the conditions (every drop at every preload, predicted from the grid) or {error}
function designCampaign(t, repeats, maxTests) {
  const grid = targetGrid(t);
  const reachable = fraction(inHull(CANDS.map((c) => [c.la, c.f]), grid));
  if (reachable === 0) {
    const amps = CANDS.map((c) => 10 ** c.la), fs = CANDS.map((c) => c.f);
    return {error: `the target ${fmtG(t.amplitude_deg[0])}-${fmtG(t.amplitude_deg[1])} deg x ${fmtG(t.frequency_hz[0])}-` +
      `${fmtG(t.frequency_hz[1])} Hz lies outside what rig ${D.rig.name} reaches with coupling ${D.coupling}: ` +
      `${fmtG(Math.min(...amps), 3)}-${fmtG(Math.max(...amps), 3)} deg at ${fmtG(Math.min(...fs), 3)}-${fmtG(Math.max(...fs), 3)} Hz`};
  }
  const limits = [];
  let step = S.level_step_decades, drops;
  for (;;) {
    drops = unique(chooseDrops(t, step));
    const nCond = drops.length * NP;
    if (!maxTests || nCond * repeats <= maxTests) break;
    if (repeats > 1) {
      const fewer = Math.max(1, Math.floor(maxTests / nCond));
      limits.push(`--max-tests ${maxTests}: ${fewer} repeat(s) per condition instead of ${repeats}`);
      repeats = fewer;
      continue;
    }
    if (step >= 1.0) {
      return {error: `${nCond} conditions (the fewest that span the target, each at ${NP} preload(s)) exceed --max-tests ${maxTests}`};
    }
    step *= 1.25;
    limits.push(`--max-tests ${maxTests}: amplitude levels ${fmtG(step, 2)} decades apart`);
  }
  const conditions = drops.flatMap((d) => D.preloads_nm.map((p, ip) => {
    const lever = D.levers.findIndex((l) => l.inertia_kgm2 === d.j), mass = D.masses_kg.indexOf(d.m);
    return {case: D.levers[lever].case, inertia_kgm2: d.j, drop_mass_kg: d.m, drop_height_m: d.h, preload_nm: p,
            repeats, ...predict(lever, mass, ip, d.h)};
  }));
  for (const c of conditions) {
    const why = problems(c);
    if (why.length) limits.push(`${c.case}, ${fmtG(c.drop_mass_kg)} kg, ${fmtG(c.drop_height_m)} m: ${why.join("; ")}`);
  }
  const covered = fraction(inHull(conditions.map((c) => [Math.log10(c.amplitude_deg), c.frequency_hz]), grid));
  return {target: t, conditions, repeats, limits, reachable, covered, nTests: conditions.length * repeats,
          unreachable: unreachable(t), doubleImpacts: conditions.filter((c) => c.double_impact).length};
}

// ---------------------------------------------------------------- outputs.py: the plan TOML
function doeDocument(design, name, baseSeed = 0) {
  const t = design.target, groups = new Map();
  for (const c of design.conditions) {
    const key = JSON.stringify([c.case, c.inertia_kgm2, c.drop_mass_kg]);
    if (!groups.has(key)) groups.set(key, {name: `${c.case}, ${fmtG(c.drop_mass_kg)} kg`, case: c.case,
                                           inertia_kgm2: c.inertia_kgm2, drop_mass_kg: c.drop_mass_kg, heights: new Set()});
    groups.get(key).heights.add(c.drop_height_m);
  }
  const sorted = [...groups.values()].sort((a, b) => (a.case < b.case ? -1 : a.case > b.case ? 1 : 0) ||
                                                     a.inertia_kgm2 - b.inertia_kgm2 || a.drop_mass_kg - b.drop_mass_kg);
  const byValue = (s) => [...s].sort((a, b) => a - b);
  return {
    name,
    description: `designed by droptower design for ${fmtG(t.amplitude_deg[0])}-${fmtG(t.amplitude_deg[1])} deg x ` +
      `${fmtG(t.frequency_hz[0])}-${fmtG(t.frequency_hz[1])} Hz: ${design.conditions.length} conditions, ` +
      `${design.nTests} tests, ${(100 * design.covered).toFixed(0)} % of the target covered`,
    source: "droptower design",
    base_seed: baseSeed,
    repeats: design.repeats,
    heights_m: byValue(new Set(design.conditions.map((c) => c.drop_height_m))),
    preloads_nm: D.preloads_nm,
    group: sorted.map((g) => ({name: g.name, inertia_kgm2: g.inertia_kgm2, drop_mass_kg: g.drop_mass_kg,
                               heights_m: byValue(g.heights)})),
  };
}

// tomli_w.dumps for this document: keys in order, arrays one item a line, [[group]] tables
function toToml(doc) {
  const str = (s) => `"${s.replace(/\\/g, "\\\\").replace(/"/g, '\\"')}"`;
  const value = (k, v) => {
    if (Array.isArray(v)) return `[\n${v.map((x) => `    ${pyFloat(x)}`).join(",\n")},\n]`;
    if (typeof v === "string") return str(v);
    return ["base_seed", "repeats"].includes(k) ? String(v) : pyFloat(v);
  };
  const table = (o) => Object.entries(o).map(([k, v]) => `${k} = ${value(k, v)}\n`).join("");
  const {group, ...top} = doc;
  return table(top) + group.map((g) => `\n[[group]]\n${table(g)}`).join("");
}

// ---------------------------------------------------------------- the page
const $ = (id) => document.getElementById(id);
const PLOT = $("plane");
const COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f"];
let current = null;  // the design shown, with its TOML

// a number for a table: 4 significant digits, no exponent
function shown(x) { return Number.isNaN(x) ? "–" : Math.abs(x) >= 1e4 ? x.toFixed(0) : fmtG(x, 4); }

function fill(select, labels) {
  select.innerHTML = labels.map((l, i) => `<option value="${i}">${l}</option>`).join("");
}

function dropRows() {  // the controls' drop
  return {lever: Number($("lever").value), mass: Number($("mass").value), preload: Number($("preload").value),
          h: Number($("height").value)};
}

const ROWS = [["amplitude_deg", "amplitude (extractor's reference) [deg]"], ["frequency_hz", "frequency [Hz]"],
  ["damping_ratio", "damping ratio [-]"], ["peak_torque_nm", "peak torque [N·m]"], ["impact_force_peak_n", "impact force peak [N]"],
  ["min_clearance_mm", "double-impact margin (min clearance) [mm]"], ["max_twist_deg", "max twist [deg]"],
  ["impact_velocity_m_per_s", "impact velocity [m/s]"]];

function showDrop() {
  const d = dropRows();
  const p = predict(d.lever, d.mass, d.preload, d.h);
  $("prediction").innerHTML = ROWS.map(([q, label]) =>
    `<tr><th>${label}</th><td id="pred-${q}">${shown(p[q])}</td></tr>`).join("");
  const why = problems(p);
  $("drop-problems").className = why.length ? "bad" : "ok";
  $("drop-problems").textContent = why.length ? why.join("; ") : "no limit hit, double-impact margin kept";
  Plotly.restyle(PLOT, {x: [[p.amplitude_deg]], y: [[p.frequency_hz]]}, [dropTrace]);
}

function setHeight(h) {
  const [lo, hi] = D.rig.drop_height_range_m;
  h = Math.min(Math.max(h, lo), hi);
  $("height").value = h;
  $("height-slider").value = Math.log(h / lo) / Math.log(hi / lo);
  showDrop();
}

function readTarget() {
  const v = ["a-lo", "a-hi", "f-lo", "f-hi"].map((id) => Number($(id).value));
  if (!v.every((x) => Number.isFinite(x) && x > 0) || v[0] > v[1] || v[2] > v[3]) return null;
  return {amplitude_deg: [v[0], v[1]], frequency_hz: [v[2], v[3]]};
}

function notes(lines) {
  const list = $("design-notes");
  list.replaceChildren(...lines.map((line) => Object.assign(document.createElement("li"), {textContent: line})));
}

function showDesign() {
  const t = readTarget();
  const repeats = Math.max(1, Math.round(Number($("repeats").value) || S.default_repeats));
  const maxTests = Math.round(Number($("max-tests").value)) || null;
  const design = t ? designCampaign(t, repeats, maxTests) : {error: "give the target as positive LOW <= HIGH"};
  current = design;
  const box = t ? [{type: "rect", xref: "x", yref: "y", x0: t.amplitude_deg[0], x1: t.amplitude_deg[1],
                    y0: t.frequency_hz[0], y1: t.frequency_hz[1], line: {dash: "dash", color: "#000"}}] : [];
  if (design.error) {
    $("design-summary").className = "bad";
    $("design-summary").textContent = design.error;
    notes([]);
    $("conditions").innerHTML = "";
    $("toml").textContent = "";
    $("download").disabled = true;
    Plotly.restyle(PLOT, {x: [[], []], y: [[], []]}, [designTrace, hullTrace]);
    Plotly.relayout(PLOT, {shapes: box});
    return;
  }
  design.toml = toToml(doeDocument(design, fileName().replace(/\.toml$/i, "")));
  $("design-summary").className = "";
  $("design-summary").textContent = `${design.conditions.length / NP} drops x ${NP} preload(s) = ${design.conditions.length} ` +
    `conditions x ${design.repeats} repeats = ${design.nTests} tests; ${(100 * design.covered).toFixed(0)} % of the target ` +
    `covered (${(100 * design.reachable).toFixed(0)} % reachable with this rig)` +
    `; ${design.doubleImpacts} double impact(s) predicted`;
  notes([...design.unreachable.map((u) => `unreachable: ${u}`), ...design.limits.map((l) => `limit: ${l}`)]);
  const cols = [["case", null], ["drop_mass_kg", "m [kg]"], ["drop_height_m", "h [m]"], ["preload_nm", "preload [N·m]"],
                ["amplitude_deg", "amplitude [deg]"], ["frequency_hz", "f [Hz]"], ["peak_torque_nm", "peak torque [N·m]"],
                ["impact_force_peak_n", "impact force [N]"], ["min_clearance_mm", "margin [mm]"]];
  $("conditions").innerHTML = `<tr>${cols.map(([q, l]) => `<th>${l || q}</th>`).join("")}</tr>` +
    design.conditions.map((c) => `<tr>${cols.map(([q]) => `<td>${typeof c[q] === "string" ? c[q] : shown(c[q])}</td>`).join("")}</tr>`).join("");
  $("toml").textContent = design.toml;
  $("download").disabled = false;
  const pts = design.conditions.map((c) => [c.amplitude_deg, c.frequency_hz]);
  const ring = convexHull(pts.map(([a, f]) => [Math.log10(a), f]));
  Plotly.restyle(PLOT, {x: [pts.map((p) => p[0]), [...ring, ring[0]].filter(Boolean).map((p) => 10 ** p[0])],
                        y: [pts.map((p) => p[1]), [...ring, ring[0]].filter(Boolean).map((p) => p[1])]}, [designTrace, hullTrace]);
  Plotly.relayout(PLOT, {shapes: box});
}

// the plan's file name as typed, ending in .toml (the plan's name is its stem, as design --out)
function fileName() {
  const name = $("file-name").value.trim() || "plan.toml";
  return /\.toml$/i.test(name) ? name : `${name}.toml`;
}

function download() {
  if (!current || current.error) return;
  const a = document.createElement("a");
  a.href = URL.createObjectURL(new Blob([current.toml], {type: "application/toml"}));
  a.download = fileName();
  document.body.appendChild(a);
  a.click();
  a.remove();
}

// the plane: every lever and mass at the chosen preload, the drop, the target and the design
let dropTrace, designTrace, hullTrace;
function curves(preload) {
  const traces = [];
  D.levers.forEach((lever, l) => D.masses_kg.forEach((m, im) => {
    const idx = D.heights_m.map((_, k) => gridIndex(l, im, preload, k));
    const colour = COLOURS[(l * NM + im) % COLOURS.length];
    const part = (ok) => idx.map((i) => (D.grid.ok[i] === ok ? D.grid.amplitude_deg[i] : null));
    traces.push({x: part(true), y: idx.map((i) => D.grid.frequency_hz[i]), mode: "lines+markers", line: {color: colour, width: 1.5},
                 marker: {size: 4}, name: `${lever.case}, ${fmtG(m)} kg`, customdata: D.heights_m,
                 hovertemplate: "h = %{customdata:.3f} m<br>%{x:.3g} deg, %{y:.3g} Hz<extra>%{fullData.name}</extra>"});
    traces.push({x: part(false), y: idx.map((i) => D.grid.frequency_hz[i]), mode: "markers", showlegend: false,
                 marker: {symbol: "x", size: 5, color: colour, opacity: 0.5}, name: `${lever.case}, ${fmtG(m)} kg: a limit hit`,
                 customdata: D.heights_m, hovertemplate: "h = %{customdata:.3f} m: a limit hit<extra>%{fullData.name}</extra>"});
  }));
  return traces;
}

function drawPlane() {
  const traces = curves(Number($("preload").value));
  hullTrace = traces.length;
  traces.push({x: [], y: [], mode: "lines", fill: "toself", fillcolor: "rgba(44,160,44,0.12)", line: {color: "rgba(44,160,44,0.5)"},
               name: "hull of the design", hoverinfo: "skip"});
  designTrace = traces.length;
  traces.push({x: [], y: [], mode: "markers", marker: {size: 11, color: "rgba(0,0,0,0)", line: {color: "#000", width: 1.5}},
               name: "designed conditions"});
  dropTrace = traces.length;
  traces.push({x: [], y: [], mode: "markers", marker: {size: 15, symbol: "star", color: "#d62728", line: {color: "#000", width: 1}},
               name: "this drop"});
  for (const tr of traces) { tr.type = "scatter"; tr.unselected = {marker: {opacity: 1}}; }
  const layout = {template: JSON.parse($("plotly-template").textContent), height: 560, margin: {l: 60, r: 10, t: 30, b: 50},
                  xaxis: {type: "log", title: {text: "amplitude [deg]"}}, yaxis: {title: {text: "frequency [Hz]"}},
                  dragmode: "select", legend: {font: {size: 10}}, hovermode: "closest",
                  title: {text: "drag a box to set the target", font: {size: 13}}};
  return Plotly.react(PLOT, traces, layout, {responsive: true, displaylogo: false});
}

function init() {
  fill($("lever"), D.levers.map((l) => l.case));
  fill($("mass"), D.masses_kg.map((m) => `${fmtG(m)} kg`));
  fill($("preload"), D.preloads_nm.map((p) => `${fmtG(p)} N·m`));
  const [lo, hi] = D.rig.drop_height_range_m;
  $("height").min = lo;
  $("height").max = hi;
  for (const id of ["lever", "mass"]) $(id).addEventListener("change", showDrop);
  $("preload").addEventListener("change", () => drawPlane().then(() => { showDrop(); showDesign(); }));
  $("height-slider").addEventListener("input", (e) => setHeight(lo * (hi / lo) ** Number(e.target.value)));
  $("height").addEventListener("change", (e) => { if (Number(e.target.value) > 0) setHeight(Number(e.target.value)); });
  for (const id of ["a-lo", "a-hi", "f-lo", "f-hi", "repeats", "max-tests", "file-name"]) $(id).addEventListener("change", showDesign);
  $("download").addEventListener("click", download);
  return drawPlane().then(() => {
    PLOT.on("plotly_selected", (ev) => {
      if (!ev || !ev.range) return;
      const [a0, a1] = [...ev.range.x].sort((a, b) => a - b);  // data values, also on the log axis
      const [f0, f1] = [...ev.range.y].sort((a, b) => a - b);
      $("a-lo").value = fmtG(a0, 2); $("a-hi").value = fmtG(a1, 2);
      $("f-lo").value = fmtG(f0, 2); $("f-hi").value = fmtG(f1, 2);
      Plotly.relayout(PLOT, {selections: []});
      showDesign();
    });
    setHeight(Number($("height").value));
    showDesign();
  });
}

// for scripts and tests: the steps of the design, the predictions, the TOML shown
window.planner = {designCampaign, chooseDrops, unreachable, doeDocument, toToml, predict, inHull, fmtG,
                  toml: () => (current && !current.error ? current.toml : null), ready: init()};
