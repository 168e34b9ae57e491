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
// A frame: axes, ticks, title; returns the scales and the SVG.
// `xaxis`: "log" (the data are log10 values), "whole" (generations, categories) or plain.
function frame(box, title, xr, yr, xlabel, ylabel, xaxis) {
  const xlog = xaxis === "log";
  box.textContent = "";
  const W = box.clientWidth || 560, H = box.clientHeight || 360;
  const m = { l: 58, r: 12, t: 22, b: 36 };
  const svg = el("svg", { width: W, height: H, viewBox: "0 0 " + W + " " + H }, box);
  const sx = (x) => m.l + ((x - xr[0]) / (xr[1] - xr[0])) * (W - m.l - m.r);
  const sy = (y) => H - m.b - ((y - yr[0]) / (yr[1] - yr[0])) * (H - m.t - m.b);
  el("rect", { x: m.l, y: m.t, width: W - m.l - m.r, height: H - m.t - m.b, fill: "none", stroke: "#999" }, svg);
  text(svg, m.l, 14, title);
  // Log axes tick at whole powers of ten (the data are log10 values there).
  ticks(xr, xlog || xaxis === "whole").forEach((x) => text(svg, sx(x), H - m.b + 14, xlog ? "1e" + x : fmt(x), "middle"));
  ticks(yr, false).forEach((y) => text(svg, m.l - 4, sy(y) + 4, fmt(y), "end"));
  text(svg, (W + m.l) / 2, H - 4, xlabel, "middle");
  const yl = text(svg, 12, (H - m.b + m.t) / 2, ylabel, "middle");
  yl.setAttribute("transform", "rotate(-90 12 " + (H - m.b + m.t) / 2 + ")");
  return { svg: svg, sx: sx, sy: sy, W: W };
}
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
  items.forEach((it, i) => {
    el("rect", { x: f.W - 150, y: 28 + i * 14, width: 10, height: 10, fill: it[1] }, f.svg);
    text(f.svg, f.W - 136, 37 + i * 14, it[0]);
  });
}

function fitnessChart(box, c) {
  const g = c.generations;
  const ys = g.flatMap((r) => [r.min, r.max, r.best_so_far]).concat(c.reference ? [c.reference.value] : []);
  const f = frame(box, "Fitness per generation", extent(g.map((r) => r.g)), extent(ys), "generation", "fitness", "whole");
  band(f, g.map((r) => [r.g, r.min, r.max]), "#4682b4");
  line(f, g.map((r) => [r.g, r.mean]), "#4682b4");
  line(f, g.map((r) => [r.g, r.best]), "#2a2");
  line(f, g.map((r) => [r.g, r.best_so_far]), "#c60", "5,3");
  const items = [["min–max", "#a9c4dc"], ["mean", "#4682b4"], ["best", "#2a2"], ["best so far", "#c60"]];
  if (c.reference) {
    const x = extent(g.map((r) => r.g));
    line(f, [[x[0], c.reference.value], [x[1], c.reference.value]], "#a00", "2,2");
    items.push([c.reference.label, "#a00"]);
  }
  legend(f, items);
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
  const state = p.diverged ? "diverged" : p.pruned ? "pruned (partial " + fmt(p.partial) + ")" : "fitness " + fmt(p.fitness);
  t.textContent = p.id + "\n" + p.activation + " δ_min " + p.delta_min + " patience " + p.patience + "\n" + state + "\nfirst in generation " + p.first;
}
function fitnessRange(pts) {
  return extent(pts.map((p) => p.fitness));
}
function explorer(box, c) {
  const pts = c.points, fr = fitnessRange(pts);
  const f = frame(box, "Population: " + pts.length + " settings (○ sigmoid □ tanh △ relu; grey pruned, red diverged)",
    extent(pts.map((p) => Math.log10(p.delta_min))), extent(pts.map((p) => p.patience)), "δ_min (log10)", "patience", "log");
  pts.forEach((p) => marker(f, p, f.sx(Math.log10(p.delta_min)), f.sy(p.patience), fr, "pt"));
}
function geneChart(box, c, title, gx, label, xaxis) {
  const pts = c.points, fr = fitnessRange(pts);
  const yv = (p) => (p.fitness !== null ? p.fitness : p.partial);
  const f = frame(box, title, extent(pts.map(gx)), extent(pts.map(yv)), label, "fitness", xaxis);
  pts.filter((p) => yv(p) !== null).forEach((p) => marker(f, p, f.sx(gx(p)), f.sy(yv(p)), fr, "gpt"));
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
  for (const k in groups) {
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
    section.appendChild(box);
    const ys = pick.flatMap((s) => [s.mean - s.ci95, s.mean + s.ci95]);
    const f = frame(box, title + " (95 % bands)", extent(pick.map(xOf)), extent(ys), xlabel, "score");
    for (const alg of ["fqi", "bfqi"]) {
      const ps = pick.filter((s) => s.algorithm === alg).sort((a, b) => xOf(a) - xOf(b));
      band(f, ps.map((s) => [xOf(s), s.mean - s.ci95, s.mean + s.ci95]), colours[alg]);
      line(f, ps.map((s) => [xOf(s), s.mean]), colours[alg]);
    }
    legend(f, [["FQI", colours.fqi], ["B-FQI", colours.bfqi]]);
  }
}

// How often the page redrew from polled data and when it first did (ms after navigation start):
// the browser test reads these to see live updates arrive without a reload.
const drawn = { count: 0, firstMs: null };
window.dashboardDrawn = drawn;
function draw(charts) {
  drawn.count += 1;
  if (drawn.firstMs === null) drawn.firstMs = performance.now();
  document.body.dataset.draws = drawn.count;
  if (!charts) return;
  const get = (id) => document.getElementById(id);
  if (charts.generations && get("fitness")) {
    fitnessChart(get("fitness"), charts);
    explorer(get("explorer"), charts);
    geneChart(get("gene-delta"), charts, "Fitness against δ_min", (p) => Math.log10(p.delta_min), "δ_min (log10)", "log");
    geneChart(get("gene-patience"), charts, "Fitness against patience", (p) => p.patience, "patience");
    geneChart(get("gene-activation"), charts, "Fitness against activation (0 sigmoid, 1 tanh, 2 relu)",
      (p) => ACT[p.activation] + ((p.patience * 7919) % 100) / 400 - 0.125, "activation", "whole");
  }
  if (charts.series && get("curves")) curves(get("curves"), charts);
}

// Replaces a table's rows with the polled ones (text and links only).
function refill(t) {
  const table = document.querySelector('table[data-table="' + CSS.escape(t.name) + '"]');
  if (!table) return;
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
      tr.appendChild(td);
    });
    body.appendChild(tr);
  });
  table.replaceChild(body, table.tBodies[0]);
  const count = table.closest("section").querySelector(".csv");
  if (count && count.lastChild) count.lastChild.textContent = " · " + t.rows.length + " rows";
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
      draw(p.charts);
    })
    .catch(() => { document.getElementById("live").textContent = "not reachable, retrying"; })
    .finally(() => setTimeout(poll, 2000));
}
poll();
