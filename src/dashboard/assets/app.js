// bfqi-ga dashboard: draws the page's charts as inline SVG and keeps its tables and charts live by
// polling the page's JSON every 2 s (no reload). Data is only ever set with textContent and
// setAttribute, never parsed as HTML.
"use strict";
const NS = "http://www.w3.org/2000/svg";
const page = document.body.dataset.page;
const jsonUrl = page + (page.includes("?") ? "&" : "?") + "json=1";

function el(name, attrs, parent) {
  const e = document.createElementNS(NS, name);
  for (const k in attrs) e.setAttribute(k, attrs[k]);
  if (parent) parent.appendChild(e);
  return e;
}
function text(parent, x, y, s, anchor) {
  const t = el("text", { x: x, y: y, "text-anchor": anchor || "start" }, parent);
  t.textContent = s;
  return t;
}
function extent(vals) {
  const f = vals.filter((v) => v !== null && v !== undefined && isFinite(v));
  if (!f.length) return [0, 1];
  let lo = Math.min(...f), hi = Math.max(...f);
  if (lo === hi) { lo -= 0.5; hi += 0.5; }
  const pad = (hi - lo) * 0.05;
  return [lo - pad, hi + pad];
}
// About five round tick values inside [lo, hi] (steps of 1, 2 or 5 times a power of ten).
function ticks(r, whole) {
  const span = r[1] - r[0];
  let step = Math.pow(10, Math.floor(Math.log10(span / 5)));
  if (span / step > 25) step *= 5;
  else if (span / step > 10) step *= 2;
  if (whole) step = Math.max(1, Math.round(step));
  const out = [];
  for (let v = Math.ceil(r[0] / step) * step; v <= r[1] + 1e-9 * span; v += step) out.push(+v.toPrecision(12));
  return out;
}
function fmt(v) {
  if (v === null || v === undefined) return "—";
  const a = Math.abs(v);
  if (a !== 0 && (a < 1e-3 || a >= 1e5)) return v.toExponential(2);
  return Number.isInteger(v) ? String(v) : String(+v.toPrecision(4));
}
// Tick positions and labels for an axis: "log" (the data are log10 values: ticks at whole powers
// of ten, or at values inside one decade when the range holds fewer than two), "whole"
// (generations, counts), "none" (the chart labels its own axes) or plain.
function axisTicks(r, kind) {
  if (kind === "none") return [];
  if (kind === "log") {
    const whole = ticks(r, true);
    if (whole.length >= 2) return whole.map((v) => [v, "1e" + v]);
    return ticks(r, false).map((v) => [v, fmt(+Math.pow(10, v).toPrecision(2))]);
  }
  // As many decimals as the step needs, so that neighbouring ticks never read alike (199.25 and
  // 199.3, not 199.3 twice).
  const ts = ticks(r, kind === "whole"), step = ts.length > 1 ? ts[1] - ts[0] : 0;
  const plain = step >= 1e-3 && ts.every((v) => Math.abs(v) < 1e5);
  const d = plain ? Math.max(0, -Math.floor(Math.log10(step) + 1e-9)) : 0;
  return ts.map((v) => [v, plain ? String(+v.toFixed(d)) : fmt(v)]);
}
// A frame: axes, ticks, title; returns the scales and the SVG. `xaxis` and `yaxis` are
// [axisTicks] kinds.
function frame(box, title, xr, yr, xlabel, ylabel, xaxis, right, yaxis) {
  box.textContent = "";
  saveLinks(box);
  const W = box.clientWidth || 560, H = box.clientHeight || 360;
  // Legends and the colour bar sit in the right margin, never over the data.
  const m = { l: 58, r: right || 12, t: 22, b: 36 };
  const svg = el("svg", { width: W, height: H, viewBox: "0 0 " + W + " " + H }, box);
  const sx = (x) => m.l + ((x - xr[0]) / (xr[1] - xr[0])) * (W - m.l - m.r);
  const sy = (y) => H - m.b - ((y - yr[0]) / (yr[1] - yr[0])) * (H - m.t - m.b);
  el("rect", { x: m.l, y: m.t, width: W - m.l - m.r, height: H - m.t - m.b, fill: "none", stroke: "#999" }, svg);
  text(svg, m.l, 14, title);
  const xt = el("g", { class: "xticks" }, svg), yt = el("g", { class: "yticks" }, svg);
  axisTicks(xr, xaxis).forEach((t) => text(xt, sx(t[0]), H - m.b + 14, t[1], "middle"));
  axisTicks(yr, yaxis).forEach((t) => text(yt, m.l - 4, sy(t[0]) + 4, t[1], "end"));
  text(svg, (W + m.l) / 2, H - 4, xlabel, "middle");
  const yl = text(svg, 12, (H - m.b + m.t) / 2, ylabel, "middle");
  yl.setAttribute("transform", "rotate(-90 12 " + (H - m.b + m.t) / 2 + ")");
  return { svg: svg, sx: sx, sy: sy, W: W, H: H, m: m };
}
// Log or linear per chart axis, as the toggle buttons last set it ("chart:x" → log), kept across
// polls. Log is offered only where every value on the axis is > 0 (a score or fitness often is
// not); the chart's default applies until the button is pressed.
const scales = {};
function scale(id, axis, vals, name, logByDefault, whole) {
  const ok = vals.filter((v) => v !== null && v !== undefined && isFinite(v));
  const offered = ok.length > 0 && ok.every((v) => v > 0);
  const key = id + ":" + axis;
  const log = offered && (key in scales ? scales[key] : !!logByDefault);
  return {
    key: key, name: name, offered: offered, log: log,
    f: log ? (v) => (v !== null && v !== undefined && v > 0 ? Math.log10(v) : null) : (v) => v,
    kind: log ? "log" : whole ? "whole" : null,
    label: name + (log ? " (log)" : ""),
  };
}
// The chart's log/linear buttons (bottom left, under the y axis's ticks), one per offered axis.
function toggles(box, list) {
  const bar = document.createElement("div");
  bar.className = "scales";
  list.filter((s) => s.offered).forEach((s) => {
    const b = document.createElement("button");
    b.className = "scale";
    b.dataset.axis = s.key;
    // Short ("x: log"), to fit under the plot; the tooltip names the axis.
    b.textContent = s.key.split(":").pop() + ": " + (s.log ? "log" : "linear");
    b.title = "show " + s.name + " on a " + (s.log ? "linear" : "log") + " axis";
    b.addEventListener("click", () => { scales[s.key] = !s.log; render(lastCharts); });
    bar.appendChild(b);
  });
  if (bar.childNodes.length) box.appendChild(bar);
}
// A "save SVG" button on a chart: the chart as a standalone SVG file.
function saveLinks(box) {
  const a = document.createElement("button");
  a.className = "save";
  a.textContent = "save SVG";
  a.addEventListener("click", () => {
    const url = URL.createObjectURL(svgBlob(box));
    const d = document.createElement("a");
    d.href = url;
    d.download = (box.id || "chart") + ".svg";
    d.click();
    setTimeout(() => URL.revokeObjectURL(url), 1000);
  });
  box.appendChild(a);
}
function svgBlob(box) {
  const svg = box.querySelector("svg").cloneNode(true);
  svg.setAttribute("xmlns", NS);
  const style = "<style>text{font:11px sans-serif;fill:#333}</style>";
  const s = new XMLSerializer().serializeToString(svg).replace(/^(<svg[^>]*>)/, "$1" + style);
  return new Blob([s], { type: "image/svg+xml" });
}
window.dashboardSvg = (id) => svgBlob(document.getElementById(id)).text();
function line(f, pts, color, dash) {
  const d = pts.filter((p) => p[1] !== null && isFinite(p[1])).map((p, i) => (i ? "L" : "M") + f.sx(p[0]) + "," + f.sy(p[1])).join("");
  if (d) el("path", { d: d, fill: "none", stroke: color, "stroke-width": 2, "stroke-dasharray": dash || "" }, f.svg);
}
function band(f, pts, color) {
  const ok = pts.filter((p) => p[1] !== null && p[2] !== null && isFinite(p[1]) && isFinite(p[2]));
  if (!ok.length) return;
  const up = ok.map((p, i) => (i ? "L" : "M") + f.sx(p[0]) + "," + f.sy(p[2])).join("");
  const down = ok.slice().reverse().map((p) => "L" + f.sx(p[0]) + "," + f.sy(p[1])).join("");
  el("path", { d: up + down + "Z", fill: color, "fill-opacity": 0.2, stroke: "none" }, f.svg);
}
function legend(f, items) {
  const x = f.W - f.m.r + 8;
  items.forEach((it, i) => {
    el("rect", { class: "legend", x: x, y: 28 + i * 14, width: 10, height: 10, fill: it[1] }, f.svg);
    text(f.svg, x + 14, 37 + i * 14, it[0]);
  });
}
// A vertical colour bar for fitness in the right margin, worst at the bottom.
function colourBar(f, fr) {
  const x = f.W - f.m.r + 14, top = f.m.t + 16, h = f.H - f.m.t - f.m.b - 32;
  const g = el("g", { class: "colourbar" }, f.svg);
  for (let i = 0; i < 20; i++) {
    el("rect", { x: x, y: top + (h * i) / 20, width: 12, height: h / 20 + 0.5, fill: colour(1 - i / 20) }, g);
  }
  text(g, x, top - 4, "fitness");
  text(g, x + 16, top + 8, fmt(fr[1]));
  text(g, x + 16, top + h, fmt(fr[0]));
}

function fitnessChart(box, c) {
  const g = c.generations;
  const ys = g.flatMap((r) => [r.min, r.max, r.mean, r.best, r.best_so_far]).concat(c.reference ? [c.reference.value] : []);
  const s = scale(box.id, "y", ys, "fitness", false), y = s.f;
  const f = frame(box, "Fitness per generation", extent(g.map((r) => r.g)), extent(ys.map(y)), "generation", s.label, "whole", 130, s.kind);
  band(f, g.map((r) => [r.g, y(r.min), y(r.max)]), "#4682b4");
  line(f, g.map((r) => [r.g, y(r.mean)]), "#4682b4");
  line(f, g.map((r) => [r.g, y(r.best)]), "#2a2");
  line(f, g.map((r) => [r.g, y(r.best_so_far)]), "#c60", "5,3");
  // Dots as well as lines: a single generation is a point, not an empty frame.
  g.forEach((r) => {
    [[r.min, "#a9c4dc"], [r.max, "#a9c4dc"], [r.mean, "#4682b4"], [r.best_so_far, "#c60"]].forEach((v) => {
      if (v[0] !== null && isFinite(v[0])) el("circle", { class: "gen", cx: f.sx(r.g), cy: f.sy(y(v[0])), r: 3, fill: v[1] }, f.svg);
    });
  });
  const items = [["min–max", "#a9c4dc"], ["mean", "#4682b4"], ["best", "#2a2"], ["best so far", "#c60"]];
  if (c.reference) {
    const x = extent(g.map((r) => r.g));
    line(f, [[x[0], y(c.reference.value)], [x[1], y(c.reference.value)]], "#a00", "2,2");
    items.push([c.reference.label, "#a00"]);
  }
  legend(f, items);
  toggles(box, [s]);
}

// Fitness to colour: dark blue (worst) to yellow (best).
function colour(t) {
  const stops = [[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]];
  t = Math.max(0, Math.min(1, t)) * 4;
  const i = Math.min(3, Math.floor(t)), u = t - i, a = stops[i], b = stops[i + 1];
  return "rgb(" + a.map((v, k) => Math.round(v + (b[k] - v) * u)).join(",") + ")";
}
// One point: a shape by activation, filled by fitness; pruned hollow grey, diverged a red cross.
function marker(f, p, x, y, fr, cls) {
  const a = el("a", { href: p.url }, f.svg);
  const fill = p.fitness !== null ? colour((p.fitness - fr[0]) / (fr[1] - fr[0])) : "none";
  const stroke = p.diverged ? "#d00" : p.pruned ? "#888" : "#333";
  const attrs = { class: cls, fill: fill, stroke: stroke, "stroke-width": p.diverged ? 2 : 1 };
  let s;
  if (p.activation === "tanh") s = el("rect", Object.assign({ x: x - 4, y: y - 4, width: 8, height: 8 }, attrs), a);
  else if (p.activation === "relu") s = el("polygon", Object.assign({ points: x + "," + (y - 5) + " " + (x - 5) + "," + (y + 4) + " " + (x + 5) + "," + (y + 4) }, attrs), a);
  else s = el("circle", Object.assign({ cx: x, cy: y, r: 4.5 }, attrs), a);
  const t = el("title", {}, s);
  const state = p.diverged ? "diverged" : p.raced ? "raced out, " + p.raced + " (partial " + fmt(p.partial) + ")"
    : p.pruned ? "pruned (partial " + fmt(p.partial) + ")" : "fitness " + fmt(p.fitness);
  t.textContent = p.id + "\n" + p.activation + " δ_min " + p.delta_min + " patience " + p.patience + "\n" + state + "\nfirst in generation " + p.first;
}
function fitnessRange(pts) {
  return extent(pts.map((p) => p.fitness));
}
function explorer(box, c) {
  const pts = c.points, fr = fitnessRange(pts);
  const sx = scale(box.id, "x", pts.map((p) => p.delta_min), "δ_min", true);
  const sy = scale(box.id, "y", pts.map((p) => p.patience), "patience", false, true);
  const f = frame(box, "Population: " + pts.length + " settings (○ sigmoid □ tanh △ relu; grey pruned or raced out, red diverged)",
    extent(pts.map((p) => sx.f(p.delta_min))), extent(pts.map((p) => sy.f(p.patience))), sx.label, sy.label, sx.kind, 70, sy.kind);
  pts.forEach((p) => marker(f, p, f.sx(sx.f(p.delta_min)), f.sy(sy.f(p.patience)), fr, "pt"));
  colourBar(f, fr);
  toggles(box, [sx, sy]);
}
// Parallel coordinates: one line per scored setting across activation, δ_min (log), patience
// and fitness, coloured by fitness. Each axis has its own value ticks, labelled left of it, so
// none reaches the colour bar in the right margin.
function parallel(box, c) {
  const pts = c.points.filter((p) => p.fitness !== null && isFinite(p.fitness)), fr = fitnessRange(pts);
  const lg = (p) => Math.log10(p.delta_min);
  const axes = [
    ["activation", (p) => ACT[p.activation], [-0.3, 2.3], [[0, "sigmoid"], [1, "tanh"], [2, "relu"]]],
    ["δ_min (log)", lg, extent(pts.map(lg)), "log"],
    ["patience", (p) => p.patience, extent(pts.map((p) => p.patience)), "whole"],
    ["fitness", (p) => p.fitness, fr, null],
  ];
  const f = frame(box, "Parallel coordinates: " + pts.length + " scored settings", [0, axes.length - 1], [0, 1], "", "", "none", 90, "none");
  const y = (a, v) => f.sy((v - a[2][0]) / (a[2][1] - a[2][0]));
  pts.forEach((p) => {
    const pl = el("polyline", { class: "pc", fill: "none", stroke: colour((p.fitness - fr[0]) / (fr[1] - fr[0])), "stroke-opacity": 0.6,
      points: axes.map((a, i) => f.sx(i) + "," + y(a, a[1](p))).join(" ") }, f.svg);
    el("title", {}, pl).textContent = p.id + " fitness " + fmt(p.fitness);
  });
  axes.forEach((a, i) => {
    const x = f.sx(i);
    el("line", { x1: x, x2: x, y1: f.sy(0), y2: f.sy(1), stroke: "#333" }, f.svg);
    // The first axis's name starts at it, the last's ends at it: both stay inside the plot's width.
    text(f.svg, x, f.sy(0) + 14, a[0], i === 0 ? "start" : i === axes.length - 1 ? "end" : "middle");
    const g = el("g", { class: "pc-ticks" }, f.svg);
    (Array.isArray(a[3]) ? a[3] : axisTicks(a[2], a[3])).forEach((t) => {
      el("line", { x1: x - 4, x2: x, y1: y(a, t[0]), y2: y(a, t[0]), stroke: "#333" }, g);
      const l = text(g, x - 6, y(a, t[0]) + 4, t[1], "end");
      l.setAttribute("paint-order", "stroke");
      l.setAttribute("stroke", "#fff");
      l.setAttribute("stroke-width", 3);
    });
  });
  colourBar(f, fr);
}
function importanceChart(box, c) {
  const imp = c.importance || [];
  const f = frame(box, "Gene importance (η², correlation ratio)", [-0.5, imp.length - 0.5], [0, 1], "gene", "η²", "none");
  imp.forEach((g, i) => {
    el("rect", { class: "bar", x: f.sx(i) - 20, width: 40, y: f.sy(g.eta2), height: f.sy(0) - f.sy(g.eta2), fill: "#4682b4" }, f.svg);
    text(f.svg, f.sx(i), f.sy(0) - 4 - (f.sy(0) - f.sy(g.eta2)), g.gene + " " + fmt(g.eta2), "middle");
  });
}
// A setting's networks: the loss each stopped at, per FQI iteration (train solid, validation
// dashed), on a log axis while every loss is > 0.
function lossChart(box, c) {
  const ls = c.losses.filter((l) => (l.train !== null && isFinite(l.train)) || (l.val !== null && isFinite(l.val)));
  if (!ls.length) { box.textContent = "no losses recorded"; return; }
  const s = scale(box.id, "y", ls.flatMap((l) => [l.train, l.val]), "loss", true), y = s.f;
  const f = frame(box, "Network losses per FQI iteration (train solid, validation dashed)",
    extent(ls.map((l) => l.iteration)), extent(ls.flatMap((l) => [y(l.train), y(l.val)])), "iteration", s.label, "whole", 130, s.kind);
  const groups = {};
  ls.forEach((l) => { const k = "dataset " + l.dataset + " net " + l.network; (groups[k] = groups[k] || []).push(l); });
  const palette = ["#4682b4", "#c60", "#2a2", "#a0a", "#a00", "#088", "#660", "#555", "#f80"];
  Object.keys(groups).forEach((k, i) => {
    const col = palette[i % palette.length], g = groups[k].sort((a, b) => a.iteration - b.iteration);
    line(f, g.map((l) => [l.iteration, y(l.train)]), col);
    line(f, g.map((l) => [l.iteration, y(l.val)]), col, "4,3");
    g.forEach((l) => {
      const v = y(l.train);
      if (v !== null && isFinite(v)) el("circle", { class: "loss", cx: f.sx(l.iteration), cy: f.sy(v), r: 2.5, fill: col }, f.svg);
    });
  });
  legend(f, Object.keys(groups).slice(0, 20).map((k, i) => [k, palette[i % palette.length]]));
  toggles(box, [s]);
}
// Fitness against one gene; `name` given when the gene's axis may be log.
function geneChart(box, c, title, gx, name, logByDefault, whole) {
  const pts = c.points, fr = fitnessRange(pts);
  const yv = (p) => (p.fitness !== null ? p.fitness : p.partial);
  const shown = pts.filter((p) => yv(p) !== null);
  // `logByDefault` null: the gene's axis is never offered a log scale.
  const sx = scale(box.id, "x", logByDefault === null ? [] : pts.map(gx), name, logByDefault, whole);
  const sy = scale(box.id, "y", shown.map(yv), "fitness", false);
  const f = frame(box, title, extent(pts.map((p) => sx.f(gx(p)))), extent(shown.map((p) => sy.f(yv(p)))), sx.label, sy.label, sx.kind, null, sy.kind);
  shown.forEach((p) => marker(f, p, f.sx(sx.f(gx(p))), f.sy(sy.f(yv(p))), fr, "gpt"));
  toggles(box, [sx, sy]);
}
const ACT = { sigmoid: 0, tanh: 1, relu: 2 };

function curves(section, c) {
  section.textContent = "";
  const groups = {};
  c.series.forEach((s) => {
    const k = s.analysis + " · " + s.learner;
    (groups[k] = groups[k] || []).push(s);
  });
  const colours = { fqi: "#4682b4", bfqi: "#c60" };
  Object.keys(groups).forEach((k, n) => {
    const rows = groups[k], analysis = rows[0].analysis;
    const key = analysis === "samples" ? "episodes" : "complexity";
    let xOf, title, xlabel, pick = rows;
    if (analysis === "iterations") {
      xOf = (s) => s.iteration; title = k + ": score per iteration"; xlabel = "iteration";
    } else {
      const last = {};
      rows.forEach((s) => { const id = s.algorithm + s[key]; if (!last[id] || last[id].iteration < s.iteration) last[id] = s; });
      pick = Object.values(last);
      xOf = (s) => parseFloat(s[key]); title = k + ": last-iteration score per " + key; xlabel = key;
    }
    const box = document.createElement("div");
    box.className = "chart";
    // A stable id: the axes' log/linear choice is kept by it across polls.
    box.id = "curve-" + n;
    section.appendChild(box);
    const ys = pick.flatMap((s) => [s.mean - s.ci95, s.mean + s.ci95]);
    // Sample sizes on a log axis by default, as the report's plot has them; scores only when > 0.
    const sx = analysis === "samples" ? scale(box.id, "x", pick.map(xOf), xlabel, true)
      : scale(box.id, "x", [], xlabel, false, analysis === "iterations");
    const sy = scale(box.id, "y", ys, "score", false), y = sy.f;
    const x = (s) => sx.f(xOf(s));
    const f = frame(box, title + " (95 % bands)", extent(pick.map(x)), extent(ys.map(y)), sx.label, sy.label, sx.kind, 80, sy.kind);
    for (const alg of ["fqi", "bfqi"]) {
      const ps = pick.filter((s) => s.algorithm === alg).sort((a, b) => x(a) - x(b));
      band(f, ps.map((s) => [x(s), y(s.mean - s.ci95), y(s.mean + s.ci95)]), colours[alg]);
      line(f, ps.map((s) => [x(s), y(s.mean)]), colours[alg]);
    }
    legend(f, [["FQI", colours.fqi], ["B-FQI", colours.bfqi]]);
    toggles(box, [sx, sy]);
  });
}

// Two runs side by side: each search's best fitness so far per generation, one colour a run.
function pairChart(box, c) {
  const runs = c.runs.filter((r) => r.generations.length);
  if (!runs.length) { box.textContent = "neither run is a search with generations: no fitness to compare"; return; }
  const colours = ["#4682b4", "#c60"];
  const ys = runs.flatMap((r) => r.generations.map((g) => g.best_so_far));
  const s = scale(box.id, "y", ys, "best fitness so far", false), y = s.f;
  const f = frame(box, "Best fitness so far per generation", extent(runs.flatMap((r) => r.generations.map((g) => g.g))),
    extent(ys.map(y)), "generation", s.label, "whole", 220, s.kind);
  runs.forEach((r) => {
    const col = colours[r.index % 2], pts = r.generations.map((g) => [g.g, y(g.best_so_far)]);
    const d = pts.filter((p) => p[1] !== null && isFinite(p[1])).map((p, i) => (i ? "L" : "M") + f.sx(p[0]) + "," + f.sy(p[1])).join("");
    if (d) el("path", { class: "curve", "data-run": r.index, d: d, fill: "none", stroke: col, "stroke-width": 2 }, f.svg);
    pts.forEach((p) => {
      if (p[1] !== null && isFinite(p[1])) el("circle", { class: "run-" + r.index, cx: f.sx(p[0]), cy: f.sy(p[1]), r: 3, fill: col }, f.svg);
    });
  });
  legend(f, runs.map((r) => [r.label, colours[r.index % 2]]));
  toggles(box, [s]);
}

// How often the page redrew from polled data and when it first did (ms after navigation start):
// the browser test reads these to see live updates arrive without a reload.
const drawn = { count: 0, firstMs: null };
window.dashboardDrawn = drawn;
// The charts last polled: a log/linear toggle redraws from them.
let lastCharts = null;
function draw(charts) {
  drawn.count += 1;
  if (drawn.firstMs === null) drawn.firstMs = performance.now();
  document.body.dataset.draws = drawn.count;
  lastCharts = charts;
  render(charts);
}
function render(charts) {
  if (!charts) return;
  const get = (id) => document.getElementById(id);
  if (charts.generations && get("fitness")) {
    fitnessChart(get("fitness"), charts);
    explorer(get("explorer"), charts);
    geneChart(get("gene-delta"), charts, "Fitness against δ_min", (p) => p.delta_min, "δ_min", true);
    geneChart(get("gene-patience"), charts, "Fitness against patience", (p) => p.patience, "patience", false, true);
    // Jittered categories (some values ≤ 0): never offered a log axis.
    geneChart(get("gene-activation"), charts, "Fitness against activation (0 sigmoid, 1 tanh, 2 relu)",
      (p) => ACT[p.activation] + ((p.patience * 7919) % 100) / 400 - 0.125, "activation", null, true);
  }
  if (charts.points && get("parallel")) parallel(get("parallel"), charts);
  if (charts.importance && get("importance")) importanceChart(get("importance"), charts);
  if (charts.losses && get("losses")) lossChart(get("losses"), charts);
  if (charts.series && get("curves")) curves(get("curves"), charts);
  if (charts.runs && get("pair")) pairChart(get("pair"), charts);
}

// Sorting (click a heading; again to reverse) and filtering (the box above each table), kept
// across live refreshes. Numbers sort as numbers, by their stored value.
const views = {};
function cellKey(td) {
  const v = td.dataset.v !== undefined ? td.dataset.v : td.textContent;
  const n = Number(v);
  return v !== "" && isFinite(n) ? n : v;
}
function applyView(table) {
  const view = views[table.dataset.table] || {};
  const rows = Array.from(table.tBodies[0].rows);
  if (view.col !== undefined) {
    rows.sort((a, b) => {
      const x = cellKey(a.cells[view.col]), y = cellKey(b.cells[view.col]);
      const c = typeof x === typeof y ? (x < y ? -1 : x > y ? 1 : 0) : typeof x === "number" ? -1 : 1;
      return view.desc ? -c : c;
    });
    rows.forEach((r) => table.tBodies[0].appendChild(r));
  }
  const q = (view.filter || "").toLowerCase();
  rows.forEach((r) => { r.hidden = q !== "" && !r.textContent.toLowerCase().includes(q); });
  Array.from(table.tHead.rows[0].cells).forEach((th, i) => {
    th.dataset.sort = view.col === i ? (view.desc ? "desc" : "asc") : "";
  });
}
function enhance(table) {
  if (table.dataset.enhanced) return;
  table.dataset.enhanced = "1";
  const name = table.dataset.table;
  views[name] = views[name] || {};
  const box = document.createElement("input");
  box.type = "search";
  box.className = "filter";
  box.placeholder = "filter rows";
  box.addEventListener("input", () => { views[name].filter = box.value; applyView(table); });
  table.closest("section").insertBefore(box, table.parentNode);
  Array.from(table.tHead.rows[0].cells).forEach((th, i) => {
    th.addEventListener("click", () => {
      const v = views[name];
      v.desc = v.col === i ? !v.desc : false;
      v.col = i;
      applyView(table);
    });
  });
}
document.querySelectorAll("table[data-table]").forEach(enhance);

// The runs table: a box to tick in each run's row; with two ticked, the button opens them side by
// side. Ticks are kept by run across live refreshes (the rows are rebuilt then).
const picked = [];
function runOf(a) {
  // `/run/R/PATH` (PATH percent-encoded) → `R/PATH` as the query's value.
  return decodeURIComponent(a.getAttribute("href").replace(/^\/run\//, ""));
}
function pickers(table) {
  if (table.dataset.table !== "runs") return;
  Array.from(table.tBodies[0].rows).forEach((tr) => {
    const a = tr.cells[0] && tr.cells[0].querySelector("a");
    if (!a || tr.cells[0].querySelector("input")) return;
    const run = runOf(a), box = document.createElement("input");
    box.type = "checkbox";
    box.className = "pick";
    box.title = "tick two runs to see them side by side";
    box.checked = picked.includes(run);
    box.addEventListener("change", () => {
      const i = picked.indexOf(run);
      if (box.checked && i < 0) picked.push(run);
      if (!box.checked && i >= 0) picked.splice(i, 1);
      // Two at most: a third tick replaces the oldest.
      while (picked.length > 2) picked.shift();
      table.querySelectorAll("input.pick").forEach((b) => { b.checked = picked.includes(runOf(b.parentNode.querySelector("a"))); });
      pickButton();
    });
    tr.cells[0].insertBefore(box, a);
  });
  pickButton();
}
function pickButton() {
  const b = document.getElementById("compare-runs");
  if (!b) return;
  b.disabled = picked.length !== 2;
  b.textContent = picked.length === 2 ? "Side by side: " + picked[0] + " and " + picked[1] : "Tick two runs to see them side by side";
}
const pickerButton = document.getElementById("compare-runs");
if (pickerButton) {
  pickerButton.addEventListener("click", () => {
    if (picked.length === 2) location.href = "/compare-runs?a=" + encodeURIComponent(picked[0]) + "&b=" + encodeURIComponent(picked[1]);
  });
}
document.querySelectorAll("table[data-table]").forEach(pickers);

// A table the page did not have when it loaded (validation, once it runs): added at the end.
function addTable(t) {
  const sec = document.createElement("section");
  const h = document.createElement("h2");
  h.textContent = t.title;
  const p = document.createElement("p");
  p.className = "csv";
  const a = document.createElement("a");
  a.setAttribute("href", page + (page.includes("?") ? "&" : "?") + "csv=" + encodeURIComponent(t.name));
  a.textContent = "CSV";
  p.appendChild(a);
  p.appendChild(document.createTextNode(""));
  const div = document.createElement("div");
  div.className = "scroll";
  const table = document.createElement("table");
  table.dataset.table = t.name;
  const tr = table.createTHead().insertRow();
  t.columns.forEach((c) => { const th = document.createElement("th"); th.textContent = c; tr.appendChild(th); });
  table.appendChild(document.createElement("tbody"));
  div.appendChild(table);
  sec.append(h, p, div);
  document.querySelector("main").appendChild(sec);
  enhance(table);
  return table;
}
function notes(list) {
  const sec = document.getElementById("notes");
  if (!sec) return;
  const ul = sec.querySelector("ul");
  ul.textContent = "";
  (list || []).forEach((n) => { const li = document.createElement("li"); li.textContent = n; ul.appendChild(li); });
  sec.hidden = !(list && list.length);
}

// Replaces a table's rows with the polled ones (text and links only).
function refill(t) {
  const table = document.querySelector('table[data-table="' + CSS.escape(t.name) + '"]') || addTable(t);
  const body = document.createElement("tbody");
  t.rows.forEach((r) => {
    const tr = document.createElement("tr");
    r.forEach((c) => {
      const td = document.createElement("td");
      if (c.link) {
        const a = document.createElement("a");
        a.setAttribute("href", c.link);
        a.textContent = c.text;
        td.appendChild(a);
      } else td.textContent = c.text;
      if (c.value !== undefined) td.dataset.v = c.value;
      tr.appendChild(td);
    });
    body.appendChild(tr);
  });
  table.replaceChild(body, table.tBodies[0]);
  const count = table.closest("section").querySelector(".csv");
  if (count && count.lastChild) count.lastChild.textContent = " · " + t.rows.length + " rows";
  pickers(table);
  applyView(table);
}

let last = "";
function poll() {
  fetch(jsonUrl, { cache: "no-store" })
    .then((r) => (r.ok ? r.text() : Promise.reject(r.status)))
    .then((s) => {
      document.getElementById("live").textContent = "live · " + new Date().toLocaleTimeString();
      if (s === last) return;
      last = s;
      const p = JSON.parse(s);
      p.tables.forEach(refill);
      notes(p.notes);
      draw(p.charts);
    })
    .catch(() => { document.getElementById("live").textContent = "not reachable, retrying"; })
    .finally(() => setTimeout(poll, 2000));
}
poll();
