// genr8 studio: the page. Polls /api/state once a second; redraws curves when a commit lands; shows
// the viewed generation's best designs in 3D (GLB grown by the server from the recorded rewrite
// systems); every action is a POST to /api/act, recorded as `genr8 edit` records an intervention.
import * as THREE from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";
import { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";
import { drawParallel, inBrushes, node as el } from "/static/parallel.js";

const $ = (id) => document.getElementById(id);
const ISLAND_COLOURS = ["#f2a541", "#59c3c3", "#e0662f", "#9b8cf2", "#7bd389", "#ef6f6c", "#f7d774",
  "#4f9de0", "#d77fb8", "#a3c76c", "#c9925a", "#6fd0b0", "#b3a4ff", "#ff9e7a", "#8fb8de", "#e6c07b"];
const islandColour = (i) => ISLAND_COLOURS[i % ISLAND_COLOURS.length];
const fmt = (v, d = 4) => (v === null || v === undefined || !isFinite(v)) ? "–" :
  Math.abs(v) < 1e-9 ? "0" : Number(v).toPrecision(d).replace(/\.?0+(e|$)/, "$1");
const fmtTime = (s) => {
  if (s === null || s === undefined || !isFinite(s)) return "–";
  s = Math.round(s);
  if (s >= 3600) return `${Math.floor(s / 3600)}h${String(Math.floor(s % 3600 / 60)).padStart(2, "0")}m`;
  if (s >= 60) return `${Math.floor(s / 60)}m${String(s % 60).padStart(2, "0")}s`;
  return `${s}s`;
};

const ui = { state: null, version: -1, viewGen: -1, follow: true, selected: null, generation: null,
  designs: new Map(), loadingToken: 0, envVersion: null, env: null };
window.studio = ui;   // read by the browser test

// ---------------------------------------------------------------------------------------------- api
async function getJSON(url) {
  const r = await fetch(url, { credentials: "same-origin" });
  const body = await r.json();
  if (!r.ok) throw new Error(body.error || r.statusText);
  return body;
}
async function act(body) {
  try {
    const r = await fetch("/api/act", { method: "POST", credentials: "same-origin",
      headers: { "Content-Type": "application/json", "X-Genr8-Studio": "1" }, body: JSON.stringify(body) });
    const answer = await r.json();
    if (!r.ok) throw new Error(answer.error || r.statusText);
    toast(answer.message);
    poll();
    return answer;
  } catch (e) { toast(e.message, true); return null; }
}
let toastTimer = null;
function toast(text, error = false) {
  const t = $("toast");
  t.textContent = text; t.className = "toast" + (error ? " error" : "");
  clearTimeout(toastTimer); toastTimer = setTimeout(() => t.classList.add("hidden"), error ? 7000 : 4000);
}

// ------------------------------------------------------------------------------------------- header
function showState(s) {
  $("run-id").textContent = s.run_id;
  const pill = $("status"); pill.textContent = s.status; pill.className = "pill " + s.status;
  const g = Math.max(s.generation, 0);
  const done = s.completed ?? s.generation, founders = s.islands.filter((i) => (i.completed ?? i.generation) >= 0).length;
  const where = done < 0 ? `evaluating the founders · <b>${founders}</b> of ${s.islands.length} islands done` :
    `generation <b>${done}</b> of ${s.last_generation}` +
    (done > s.generation ? ` <span class="live" title="completed by every island; committed up to ${s.generation}">· committed ${s.generation < 0 ? "none yet" : "to " + s.generation}</span>` : "");
  $("gen-label").innerHTML = where + ` · ${s.islands.length} island${s.islands.length > 1 ? "s" : ""} × ${s.population}`;
  $("gen-bar").style.width = `${Math.min(100, 100 * (Math.max(done, 0) + (done < 0 ? founders / s.islands.length : 1)) / (s.last_generation + 1))}%`;
  $("rate").textContent = s.individuals_per_second ? s.individuals_per_second.toFixed(1) : "–";
  $("left").textContent = s.status === "complete" ? "done" : fmtTime(s.seconds_left);
  const bests = s.islands.map((i) => i.best).filter((b) => b !== null);
  $("best").textContent = bests.length ? fmt(Math.min(...bests)) : "–";
  const pause = $("pause");
  pause.disabled = !(s.status === "running" || s.status === "paused");
  pause.textContent = s.status === "paused" ? "Continue" : "Pause";
  $("islands").innerHTML = s.islands.map((i) =>
    `<div class="chip${(i.completed ?? i.generation) > i.generation ? " live" : ""}" title="${(i.completed ?? i.generation) > i.generation ? "completed, not yet committed" : "committed"}"><i style="background:${islandColour(i.island)}"></i>i${i.island} · g${Math.max(i.completed ?? i.generation, i.generation)}${(i.completed ?? i.generation) > i.generation ? "*" : ""} · ${fmt(i.best, 3)}</div>`).join("");
  const filter = $("island-filter");
  if (filter.options.length !== s.islands.length + 1) {
    filter.innerHTML = `<option value="">all</option>` + s.islands.map((i) => `<option value="${i.island}">${i.island}</option>`).join("");
  }
  $("interventions").innerHTML = s.interventions.length ? s.interventions.slice().reverse().map((e) =>
    `<li class="${e.kind}"><b>gen ${e.generation}</b> · ${e.label} <small class="muted">(${e.source})</small>` +
    `<span>${e.what.map(escapeHTML).join("<br>") || ""}</span></li>`).join("") :
    `<li class="pause"><span>none yet — favour a design, set a fitness or change a weight</span></li>`;
  $("queue").innerHTML = s.queued.map((q) => `<div>queued #${q.number}: ${escapeHTML(q.label)} — at the next epoch</div>`).join("");
  fillSteer(s);
}
const escapeHTML = (t) => String(t).replace(/[&<>"]/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;" }[c]));

// ------------------------------------------------------------------------------------------- charts
function extent(values) {
  let lo = Infinity, hi = -Infinity;
  for (const v of values) if (v !== null && isFinite(v)) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
  if (lo === Infinity) return [0, 1];
  if (hi - lo < 1e-12) { const p = Math.abs(lo) * 0.05 || 0.5; return [lo - p, hi + p]; }
  return [lo, hi];
}
function path(xs, ys, sx, sy) {
  let d = "", pen = false;
  for (let i = 0; i < xs.length; i++) {
    const y = ys[i];
    if (y === null || !isFinite(y)) { pen = false; continue; }
    d += `${pen ? "L" : "M"}${sx(xs[i]).toFixed(1)},${sy(y).toFixed(1)}`; pen = true;
  }
  return d;
}
function lineChart(svg, xs, series, opts = {}) {
  svg.innerHTML = "";
  const W = opts.width || 340, H = opts.height || 190, L = opts.left ?? 40, R = 8, T = opts.top ?? 20, B = opts.bottom ?? 18;
  svg.setAttribute("viewBox", `0 0 ${W} ${H}`);
  const [x0, x1] = xs.length ? [xs[0], Math.max(xs[xs.length - 1], xs[0] + 1)] : [0, 1];
  let [y0, y1] = opts.yRange || extent(series.flatMap((s) => s.scale === false ? [] : s.ys).concat(opts.extraY || []));
  const pad = (y1 - y0) * 0.06; y0 -= pad; y1 += pad;
  const sx = (x) => L + (x - x0) / (x1 - x0) * (W - L - R);
  const sy = (y) => T + (1 - (Math.min(Math.max(y, y0), y1) - y0) / (y1 - y0)) * (H - T - B);
  if (opts.axes !== false) {
    for (let k = 0; k <= 3; k++) {
      const y = y0 + (y1 - y0) * k / 3;
      el("line", { x1: L, x2: W - R, y1: sy(y), y2: sy(y), stroke: "#262e39", "stroke-width": 1 }, svg);
      el("text", { x: L - 4, y: sy(y) + 3, "text-anchor": "end", class: "axis" }, svg).textContent = fmt(y, 3);
    }
    el("text", { x: L, y: H - 4, class: "axis" }, svg).textContent = x0;
    el("text", { x: W - R, y: H - 4, "text-anchor": "end", class: "axis" }, svg).textContent = xs.length ? xs[xs.length - 1] : "";
  }
  // intervention markers with labels that never overlap: each goes to the first free row
  const rows = [];
  for (const m of opts.markers || []) {
    const x = sx(m.x);
    el("line", { x1: x, x2: x, y1: T - 2, y2: H - B, stroke: "#f2a541", "stroke-dasharray": "3 3", "stroke-opacity": 0.7 }, svg);
    if (!opts.labels) continue;
    const width = m.label.length * 5.2 + 6;
    const at = Math.min(Math.max(x, L + width / 2), W - R - width / 2);   // kept inside the chart
    let row = rows.findIndex((right) => at - width / 2 > right + 3);
    if (row < 0 && rows.length < 3) { row = rows.length; rows.push(-Infinity); }
    if (row < 0) continue;
    rows[row] = at + width / 2;
    el("text", { x: at, y: 9 + row * 10, "text-anchor": "middle", class: "marker-label" }, svg).textContent = m.label;
  }
  for (const t of opts.targets || []) {
    el("line", { x1: L, x2: W - R, y1: sy(t), y2: sy(t), stroke: "#8a94a3", "stroke-dasharray": "4 3", "stroke-width": 1 }, svg);
  }
  for (const s of series) {
    el("path", { d: path(xs, s.ys, sx, sy), fill: "none", stroke: s.colour, "stroke-width": s.width || 1.5,
      "stroke-opacity": s.opacity ?? 1, "stroke-linejoin": "round" }, svg);
  }
  if (opts.cursor !== undefined && opts.cursor >= x0) {
    const x = sx(opts.cursor);
    el("line", { x1: x, x2: x, y1: T - 2, y2: H - B, stroke: "#59c3c3", "stroke-opacity": 0.5 }, svg);
  }
}
function markers(s) {
  // one label per generation: interventions taking effect at the same generation are merged
  const byGen = new Map();
  for (const e of s.interventions) {
    if (e.kind === "continue") continue;
    const list = byGen.get(e.generation) || [];
    list.push(e.label); byGen.set(e.generation, list);
  }
  return [...byGen].map(([g, labels]) => ({ x: g, label: labels.join("+") }));
}
let curves = null;
function drawCurves() {
  if (!curves || !ui.state) return;
  const xs = curves.generation, s = ui.state;
  const islands = Object.entries(curves.islands);
  const series = [];
  if (islands.length > 1) {
    for (const [i, c] of islands) {
      const ys = xs.map((g) => { const k = c.generation.indexOf(g); return k < 0 ? null : c.best[k]; });
      series.push({ ys, colour: islandColour(Number(i)), width: 1, opacity: 0.45, scale: false });
    }
  }
  series.push({ ys: curves.mean, colour: "#59c3c3", width: 1.5, opacity: 0.9 });
  series.push({ ys: curves.best, colour: "#f2a541", width: 2.4 });
  // the range follows the best curve and the usual mean: a few wild means do not flatten the best
  const means = curves.mean.filter((v) => v !== null && isFinite(v)).sort((a, b) => a - b);
  const [lo, hiBest] = extent(curves.best);
  const hi = Math.max(hiBest, means.length ? means[Math.floor(means.length * 0.8)] : hiBest);
  lineChart($("fitness-chart"), xs, series, { markers: markers(s), labels: true, cursor: ui.viewGen,
    yRange: hi > lo ? [lo, hi] : undefined });
  $("fitness-legend").innerHTML = `<span style="--c:#f2a541">best</span><span style="--c:#59c3c3">mean of the valid</span>` +
    (islands.length > 1 ? `<span style="--c:#9b8cf2">each island's best (island colours)</span>` : "");
  const box = $("criteria-charts");
  if (box.children.length !== s.criteria.length) {
    box.innerHTML = s.criteria.map((c) => `<figure><figcaption>${c.name.replace("_", " ")} <b id="cv-${c.name}"></b></figcaption>` +
      `<svg id="cc-${c.name}" viewBox="0 0 160 62" preserveAspectRatio="none"></svg></figure>`).join("");
  }
  for (const c of s.criteria) {
    const ys = curves.criteria[c.name] || [];
    const targets = c.target !== null && c.weight ? [c.target] : [];
    lineChart($(`cc-${c.name}`), xs, [{ ys, colour: c.weight ? "#59c3c3" : "#5f6977", width: 1.6 }],
      { width: 160, height: 62, left: 4, top: 4, bottom: 4, axes: false, targets, extraY: targets,
        markers: markers(s), labels: false });
    const last = ys.length ? ys[ys.length - 1] : null;
    $(`cv-${c.name}`).textContent = `${fmt(last, 3)}${targets.length ? " → " + fmt(c.target, 3) : ""}`;
  }
  document.body.dataset.curvePoints = String(xs.length);
}

// ---------------------------------------------------------------------------------------- 3D scene
const viewport = $("viewport");
const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true, alpha: true });
renderer.setPixelRatio(Math.min(window.devicePixelRatio, 2));
renderer.setClearColor(0x000000, 0);
viewport.appendChild(renderer.domElement);
const scene = new THREE.Scene();
const camera = new THREE.PerspectiveCamera(40, 1, 0.01, 5000);
camera.up.set(0, 0, 1);
camera.position.set(12, -16, 11);
const controls = new OrbitControls(camera, renderer.domElement);
controls.enableDamping = true;
scene.add(new THREE.HemisphereLight(0xdfe8ff, 0x2a2118, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 2.2); sun.position.set(8, -6, 14); scene.add(sun);
const rim = new THREE.DirectionalLight(0x88aaff, 0.8); rim.position.set(-10, 12, 4); scene.add(rim);
const world = new THREE.Group(); scene.add(world);
const floor = new THREE.GridHelper(10, 10, 0x2b3440, 0x1c232c);
floor.rotation.x = Math.PI / 2; scene.add(floor);
const loader = new GLTFLoader();

function resize() {
  const w = viewport.clientWidth, h = viewport.clientHeight;
  renderer.setSize(w, h, false); renderer.domElement.style.width = w + "px"; renderer.domElement.style.height = h + "px";
  camera.aspect = w / Math.max(h, 1); camera.updateProjectionMatrix();
}
new ResizeObserver(resize).observe(viewport);
resize();
(function loop() { requestAnimationFrame(loop); controls.update(); renderer.render(scene, camera); })();

const rankColour = (t) => new THREE.Color().lerpColors(new THREE.Color("#f2a541"), new THREE.Color("#4f9de0"), t);

function labelSprite(text, colour) {
  const c = document.createElement("canvas"); c.width = 512; c.height = 96;
  const g = c.getContext("2d");
  g.fillStyle = "rgba(14,17,22,0.78)"; g.beginPath(); g.roundRect(4, 12, 504, 72, 18); g.fill();
  g.fillStyle = colour; g.fillRect(22, 38, 20, 20);
  g.font = "500 38px ui-monospace, monospace"; g.fillStyle = "#e6e9ee"; g.textBaseline = "middle";
  g.fillText(text, 56, 49);
  const sprite = new THREE.Sprite(new THREE.SpriteMaterial({ map: new THREE.CanvasTexture(c), depthTest: false, transparent: true }));
  sprite.renderOrder = 10;
  return sprite;
}

function environmentGroup(env, size) {
  const g = new THREE.Group();
  const r = Math.max(size * 0.028, 0.05);
  const ball = (p, colour) => {
    const m = new THREE.Mesh(new THREE.SphereGeometry(r, 20, 14), new THREE.MeshStandardMaterial({ color: colour, emissive: colour, emissiveIntensity: 0.45 }));
    m.position.set(...p); g.add(m);
    const stem = new THREE.BufferGeometry().setFromPoints([new THREE.Vector3(p[0], p[1], 0), new THREE.Vector3(...p)]);
    g.add(new THREE.Line(stem, new THREE.LineDashedMaterial({ color: colour, dashSize: r, gapSize: r, transparent: true, opacity: 0.5 })).computeLineDistances());
  };
  env.attractors.forEach((a) => ball(a.position, "#7bd389"));
  env.repellers.forEach((a) => ball(a.position, "#ef6f6c"));
  const lineMat = new THREE.LineBasicMaterial({ color: 0x8a94a3, transparent: true, opacity: 0.16 });
  for (const b of env.boundaries) {
    // each boundary's outline as segments (Boundary.sketch); an unbounded one (a plane) is given one
    // unit wide around its anchor and drawn as wide as the design
    const k = b.anchor ? size : 1, o = b.anchor || [0, 0, 0];
    const pts = b.segments.flat().map((p) => new THREE.Vector3(...p.map((v, i) => o[i] + (v - o[i]) * k)));
    g.add(new THREE.LineSegments(new THREE.BufferGeometry().setFromPoints(pts), lineMat));
  }
  return g;
}

function envExtent(env) {
  // the width (x, y) of the boundaries drawn with each design, so that cells do not overlap
  let w = 0;
  for (const b of env.boundaries) {
    if (!b.reach.length) continue;
    const lo = [0, 1].map((i) => Math.min(...b.reach.map((p) => p[i]))), hi = [0, 1].map((i) => Math.max(...b.reach.map((p) => p[i])));
    w = Math.max(w, Math.max(hi[0] - lo[0], hi[1] - lo[1]) + 2 * Math.hypot((lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2));
  }
  return w;
}

function layout() {
  const items = [...ui.designs.values()].filter((d) => d.object);
  if (!items.length) return;
  let size = 1;
  for (const d of items) size = Math.max(size, d.size);
  if (ui.env && $("show-env").checked) size = Math.max(size, envExtent(ui.env));
  const cell = size * 1.35, cols = Math.ceil(Math.sqrt(ui.order.length));
  ui.order.forEach((id, k) => {
    const d = ui.designs.get(id); if (!d || !d.object) return;
    const col = k % cols, row = Math.floor(k / cols);
    d.holder.position.set((col - (cols - 1) / 2) * cell, -(row - (Math.ceil(ui.order.length / cols) - 1) / 2) * cell, 0);
    d.label.position.set(d.centre.x, d.centre.y - size * 0.66, 0.02);
    d.label.scale.set(size * 0.9, size * 0.169, 1);
  });
  ui.cell = cell;
  const rows = Math.ceil(ui.order.length / cols);
  floor.scale.set(cols * cell / 10, 1, rows * cell / 10);
}

function frame(box) {
  const c = box.getCenter(new THREE.Vector3()), s = box.getSize(new THREE.Vector3()).length() || 1;
  controls.target.copy(c);
  const distance = (s / 2) / Math.sin(THREE.MathUtils.degToRad(camera.fov / 2)) * (camera.aspect < 1 ? 1.5 : 1.05);
  camera.position.copy(c).add(new THREE.Vector3(0.45, -0.75, 0.75).normalize().multiplyScalar(distance));
  camera.near = s / 500; camera.far = s * 50; camera.updateProjectionMatrix();
}
// the whole grid the designs will fill, framed when the first of them has loaded (framing that one
// alone would zoom onto it until the last arrives)
function frameGrid() {
  const n = (ui.order || []).length, cols = Math.ceil(Math.sqrt(n)), rows = Math.ceil(n / Math.max(cols, 1));
  const cell = ui.cell || 1;
  frame(new THREE.Box3(new THREE.Vector3(-cols * cell / 2, -rows * cell / 2, 0), new THREE.Vector3(cols * cell / 2, rows * cell / 2, cell / 2)));
}
function frameAll() { const b = new THREE.Box3().setFromObject(world); if (!b.isEmpty()) frame(b); }

async function showDesigns(ids, generationRows) {
  const token = ++ui.loadingToken;
  for (const d of ui.designs.values()) world.remove(d.holder);
  ui.designs.clear(); ui.order = ids;
  document.body.dataset.surfaces = "0";
  if (!ids.length) return;
  $("loading").classList.remove("hidden");
  const rows = new Map(generationRows.map((r) => [r.id, r]));
  let loaded = 0, first = true;
  const queue = ids.slice();
  const work = async () => {
    while (queue.length) {
      const id = queue.shift();
      const rank = ids.indexOf(id);
      try {
        const gltf = await loader.loadAsync(`/api/surface?id=${id}`);
        if (token !== ui.loadingToken) return;
        const holder = new THREE.Group(), object = gltf.scene;
        const colour = rankColour(ids.length > 1 ? rank / (ids.length - 1) : 0);
        object.traverse((o) => {
          if (o.isMesh) {
            o.geometry.computeVertexNormals();
            o.material = new THREE.MeshStandardMaterial({ color: colour, roughness: 0.55, metalness: 0.05, side: THREE.DoubleSide,
              polygonOffset: true, polygonOffsetFactor: 1, polygonOffsetUnits: 1 });
            o.userData.id = id;
          } else if (o.isLine || o.isLineSegments) {
            o.material = new THREE.LineBasicMaterial({ color: 0x0e1116, transparent: true, opacity: 0.45 });  // the scaffold: B-spline curves of the region outlines
          }
        });
        const box = new THREE.Box3().setFromObject(object);
        const row = rows.get(id) || {};
        const kind = ui.kinds ? ui.kinds.representatives.find((r) => r.id === id) : null;
        const label = labelSprite(kind ? `${id}  ×${kind.members}  ${fmt(row.fitness, 3)}` : `${id}  ${fmt(row.fitness, 3)}`,
          islandColour(row.island ?? 0));
        holder.add(object, label);
        if (ui.env && $("show-env").checked) holder.add(environmentGroup(ui.env, box.getSize(new THREE.Vector3()).length()));
        world.add(holder);
        const size = Math.max(box.getSize(new THREE.Vector3()).x, box.getSize(new THREE.Vector3()).y, 1e-3);
        ui.designs.set(id, { id, holder, object, label, colour, size, centre: box.getCenter(new THREE.Vector3()) });
        loaded++;
        document.body.dataset.surfaces = String(loaded);
        layout();
        if (first) { first = false; frameGrid(); } else if (loaded === ids.length) frameAll();
        if (ui.selected === id) highlight();
      } catch (e) {
        // a design without a surface (failed before growth) is left out of the view
      }
    }
  };
  await Promise.all([work(), work(), work()]);
  if (token === ui.loadingToken) { $("loading").classList.add("hidden"); layout(); frameAll(); highlight(); }
}

let outline = null;
function highlight() {
  if (outline) { world.remove(outline); outline = null; }
  for (const d of ui.designs.values()) d.object.traverse((o) => { if (o.isMesh) o.material.emissive?.set(0x000000); });
  const d = ui.designs.get(ui.selected);
  if (!d) return;
  d.object.traverse((o) => { if (o.isMesh) { o.material.emissive.set(0x5a3a08); } });
  d.holder.updateMatrixWorld(true);
  outline = new THREE.Box3Helper(new THREE.Box3().setFromObject(d.object), 0xf2a541);
  world.add(outline);
}

// click to select (a press that did not drag)
const ray = new THREE.Raycaster(); let pressed = null;
renderer.domElement.addEventListener("pointerdown", (e) => { pressed = [e.clientX, e.clientY]; });
renderer.domElement.addEventListener("pointerup", (e) => {
  if (!pressed || Math.hypot(e.clientX - pressed[0], e.clientY - pressed[1]) > 4) return;
  const r = renderer.domElement.getBoundingClientRect();
  ray.setFromCamera(new THREE.Vector2((e.clientX - r.left) / r.width * 2 - 1, -(e.clientY - r.top) / r.height * 2 + 1), camera);
  const hit = ray.intersectObjects(world.children, true).find((h) => h.object.userData.id);
  if (hit) select(hit.object.userData.id);
});

// ------------------------------------------------------------------------------------ the archive
async function drawArchive(g) {
  const panel = $("archive-panel");
  if (!ui.state || ui.state.search !== "map-elites") { panel.classList.add("hidden"); return; }
  const a = await getJSON(`/api/archive?g=${g}`);
  if (!a) { panel.classList.add("hidden"); return; }
  panel.classList.remove("hidden");
  const [nx, ny, nz] = [a.bins[0], a.bins[1] || 1, a.bins[2] || 1];
  const rows = ny * nz, W = 340, H = 160, L = 8, T = 6, cw = (W - 2 * L) / nx, ch = (H - T - 16) / rows;
  const svg = $("archive"); svg.innerHTML = "";
  const fits = a.cells.map((c) => c.fitness).filter((f) => f !== null);
  const [lo, hi] = extent(fits);
  const byCell = new Map(a.cells.map((c) => [c.bins.join(","), c]));
  for (let i = 0; i < nx; i++) for (let j = 0; j < ny; j++) for (let k = 0; k < nz; k++) {
    const key = [i, j, k].slice(0, a.bins.length).join(","), c = byCell.get(key);
    const y = T + (rows - 1 - (j * nz + k)) * ch;
    const fill = c ? "#" + rankColour(hi > lo ? (c.fitness - lo) / (hi - lo) : 0).getHexString() : "#1f262f";
    const r = el("rect", { x: L + i * cw + 1, y: y + 1, width: cw - 2, height: ch - 2, rx: 3, fill,
      stroke: c && c.id === ui.selected ? "#e6e9ee" : "none", "stroke-width": 1.5 }, svg);
    if (c) { r.style.cursor = "pointer"; r.addEventListener("click", () => select(c.id));
      el("title", {}, r).textContent = `${c.id} · fitness ${fmt(c.fitness, 4)}`; }
  }
  el("text", { x: L, y: H - 3, class: "axis" }, svg).textContent = `${a.descriptors[0]} →`;
  $("archive-axes").textContent = `${a.cells.length} of ${a.bins.reduce((p, b) => p * b, 1)} cells filled · ` +
    `${a.descriptors.join(" × ")} · click a cell`;
}

// ------------------------------------------------------------------------------------ generations
async function loadGeneration(g) {
  const data = await getJSON(`/api/generation?g=${g}`);
  ui.generation = data; ui.viewGen = data.generation;
  $("gen-view").innerHTML = `generation ${data.generation}` + (data.durable === false ?
    ` <span class="live" title="what the islands have completed; shown before its commit">· ${data.islands.length} island${data.islands.length === 1 ? "" : "s"}, not yet committed</span>` : "");
  document.body.dataset.generation = String(data.generation);
  document.body.dataset.durable = String(data.durable !== false);
  const island = $("island-filter").value;
  const rows = data.individuals.filter((r) => island === "" || String(r.island) === island);
  $("gen-list").innerHTML = rows.filter((r) => !ui.brushes.size || brushed(r)).slice(0, 80).map((r) =>
    `<div data-id="${r.id}" class="${r.valid ? "" : "invalid"}${r.id === ui.selected ? " selected" : ""}">` +
    `<b><i style="color:${islandColour(r.island)}">■</i> ${r.id}${r.pareto ? ' <em title="on the Pareto front">◆</em>' : ""}</b>` +
    `<span>${r.origin}</span><b>${fmt(r.fitness, 4)}</b></div>`).join("");
  const version = rows.length ? rows[0].config_version : null;
  if (version !== ui.envVersion) { ui.env = await getJSON(`/api/environment?version=${version ?? ""}`); ui.envVersion = version; }
  ui.pcRows = rows; drawPC(); drawObjectives();
  const pool = ui.brushes.size ? rows.filter(brushed) : rows;   // a brush on the criteria chooses the designs
  const choice = $("count").value;
  let shown = choice === "pareto" ? pool.filter((r) => r.pareto).slice(0, 36) :
    pool.filter((r) => r.valid).slice(0, choice === "kinds" ? 12 : Number(choice));
  ui.kinds = null;
  if (choice === "kinds") {
    const kinds = await loadKinds(data.generation, island);
    if (kinds && kinds.representatives.length) shown = kinds.representatives;
  } else { $("kinds-panel").classList.add("hidden"); }
  showDesigns(shown.map((r) => r.id), rows);
  drawArchive(data.generation).catch(() => {});
  drawCurves();
}
// the kinds of form of a generation (Biomorpher's 12): the least alike in outline, height field and curvature
async function loadKinds(g, island) {
  const panel = $("kinds-panel"), list = $("kinds-list");
  panel.classList.remove("hidden");
  list.innerHTML = `<div class="note">clustering generation ${g}…</div>`;
  let k;
  try { k = await getJSON(`/api/clusters?g=${g}&k=12&island=${island}`); } catch (e) { list.innerHTML = `<div class="note">${escapeHTML(e.message)}</div>`; return null; }
  if (!k.representatives.length) {
    list.innerHTML = `<div class="note">${escapeHTML(k.message || "no valid design to cluster")}</div>`;
    $("kinds-note").textContent = "";
    return null;
  }
  ui.kinds = k;
  $("kinds-note").textContent = `${k.representatives.length} kinds among the best ${k.surfaces} distinct surfaces · the least alike in outline, height and curvature`;
  list.innerHTML = k.representatives.map((r) =>
    `<div data-id="${r.id}" class="${r.id === ui.selected ? "selected" : ""}">` +
    `<b><i style="color:${islandColour(r.island)}">■</i> kind ${r.cluster} · ${r.id}</b>` +
    `<span>${r.members} form${r.members > 1 ? "s" : ""}</span><b>${fmt(r.fitness, 4)}</b></div>` +
    `<div class="ranges" data-kind="${r.cluster}">${Object.entries(r.ranges || {}).map(([n, [lo, hi]]) =>
      `${n.replace("_", " ")} <b>${lo === null ? "–" : fmt(lo, 3) === fmt(hi, 3) ? fmt(lo, 3) : `${fmt(lo, 3)}–${fmt(hi, 3)}`}</b>`).join(" · ")}</div>`).join("");
  document.body.dataset.kinds = String(k.representatives.length);
  return k;
}
$("kinds-list").addEventListener("click", (e) => { const row = e.target.closest("[data-id]"); if (row) select(row.dataset.id); });
$("gen-list").addEventListener("click", (e) => { const row = e.target.closest("[data-id]"); if (row) select(row.dataset.id); });
$("gen-prev").onclick = () => { $("follow").checked = ui.follow = false; if (ui.viewGen > 0) loadGeneration(ui.viewGen - 1); };
$("gen-next").onclick = () => { if (ui.state && ui.viewGen < Math.max(ui.state.generation, ui.state.completed ?? -1)) loadGeneration(ui.viewGen + 1); };
$("follow").onchange = (e) => { ui.follow = e.target.checked; if (ui.follow && ui.state) loadGeneration(Math.max(ui.state.completed ?? ui.state.generation, ui.state.generation)); };
$("count").onchange = () => loadGeneration(ui.viewGen);
$("island-filter").onchange = () => loadGeneration(ui.viewGen);
$("show-env").onchange = () => loadGeneration(ui.viewGen);
$("focus").onclick = () => { const d = ui.designs.get(ui.selected); if (d) { d.holder.updateMatrixWorld(true); frame(new THREE.Box3().setFromObject(d.object)); } };
$("overview").onclick = frameAll;

// ------------------------------------------------------------------------- parallel coordinates
// Wallacei's view: every valid design of the generation as a line across its fitness and weighted
// criteria (raw values; the target marked on each axis). Dragging along an axis brushes a range; the
// designs inside every brush are the ones listed and shown in 3D. Click a line to select its design.
ui.brushes = new Map();
function pcAxes() {
  const crits = (ui.state ? ui.state.criteria : []).filter((c) => c.weight);
  return [{ key: "fitness", label: "fitness", get: (r) => r.fitness, target: null },
    ...crits.map((c) => ({ key: c.name, label: c.name.replace("_", " "), get: (r) => (r.criteria || {})[c.name] ?? null, target: c.target }))];
}
const brushed = (r) => inBrushes(r, ui.pcAxes || pcAxes(), ui.brushes);
function drawPC() {
  const svg = $("pc"), panel = $("pc-panel");
  panel.classList.toggle("hidden", !$("show-pc").checked);
  $("centre").classList.toggle("with-pc", $("show-pc").checked);
  const rows = (ui.pcRows || []).filter((r) => r.valid);
  ui.pcAxes = pcAxes();
  drawParallel(svg, { rows, axes: ui.pcAxes, brushes: ui.brushes, selected: ui.selected,
    colour: (rank, n) => rankColour(n > 1 ? rank / (n - 1) : 0).getStyle(), onSelect: select,
    onBrushEnd: () => loadGeneration(ui.viewGen),
    onDraw: (inside) => {
      $("pc-count").textContent = ui.brushes.size ? `${inside} of ${rows.length} designs brushed` : `${rows.length} designs`;
      document.body.dataset.brushed = String(ui.brushes.size ? inside : rows.length);
    } });
}
$("show-pc").onchange = () => { drawPC(); resize(); frameAll(); drawObjectives(); };
$("pc-clear").onclick = () => { ui.brushes.clear(); loadGeneration(ui.viewGen); };
window.addEventListener("resize", drawPC);


// ------------------------------------------------------------------------------- objective space
// Octopus's view: the viewed generation's valid designs as points in the space of 2 or 3 objectives
// the designer picks (each criterion's weighted distance to its target, as the Pareto search scores
// it; lower is better), turnable in 3D; the non-dominated ones in these objectives are larger and
// amber, the others blue (dimmed when a parallel-coordinates brush leaves them out). A click on a
// point selects its design and shows its surface.
const objView = $("obj-view");
const oRenderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true, alpha: true });
oRenderer.setPixelRatio(Math.min(window.devicePixelRatio, 2));
oRenderer.setClearColor(0x000000, 0);
objView.appendChild(oRenderer.domElement);
const oScene = new THREE.Scene();
const oCamera = new THREE.PerspectiveCamera(40, 1, 0.01, 500);
oCamera.up.set(0, 0, 1);
const oControls = new OrbitControls(oCamera, oRenderer.domElement);
oControls.enableDamping = true;
oScene.add(new THREE.HemisphereLight(0xdfe8ff, 0x2a2118, 2.0));
const oSun = new THREE.DirectionalLight(0xffffff, 1.6); oSun.position.set(6, -8, 12); oScene.add(oSun);
const oGroup = new THREE.Group(); oScene.add(oGroup);
const CUBE = 10;
function oResize() {
  const w = objView.clientWidth, h = objView.clientHeight;
  if (!w || !h) return;
  oRenderer.setSize(w, h, false); oRenderer.domElement.style.width = w + "px"; oRenderer.domElement.style.height = h + "px";
  oCamera.aspect = w / Math.max(h, 1); oCamera.updateProjectionMatrix();
}
new ResizeObserver(oResize).observe(objView);
(function oLoop() { requestAnimationFrame(oLoop); if (ui.objectivesOn) { oControls.update(); oRenderer.render(oScene, oCamera); } })();

function objectiveChoices() { return (ui.state ? ui.state.criteria : []).filter((c) => c.weight); }
function fillObjectives() {
  const crits = objectiveChoices();
  if (!crits.length || $("obj-x").options.length) return;
  const preferred = ((ui.state && ui.state.objectives) || []).filter((n) => crits.some((c) => c.name === n));
  const names = [...preferred, ...crits.map((c) => c.name).filter((n) => !preferred.includes(n))];
  const opts = (extra) => extra + crits.map((c) => `<option value="${c.name}">${c.name.replace("_", " ")}</option>`).join("");
  $("obj-x").innerHTML = opts(""); $("obj-y").innerHTML = opts("");
  $("obj-z").innerHTML = opts(`<option value="">none (2D)</option>`);
  $("obj-x").value = names[0]; $("obj-y").value = names[1] || names[0]; $("obj-z").value = names[2] || "";
}
// the objective of criterion c for row r: weight * |raw - target| / unit (raw when there is no target)
function objective(c, r) {
  const v = (r.criteria || {})[c.name];
  if (v === null || v === undefined || !Number.isFinite(v)) return null;
  return c.target === null || c.target === undefined ? v : (c.weight || 1) * Math.abs(v - c.target) / (c.unit || 1);
}
// which points no other point dominates (all objectives lower or equal, one lower)
function nonDominated(points) {
  return points.map((p, i) => !points.some((q, j) => j !== i &&
    q.every((v, k) => v <= p[k]) && q.some((v, k) => v < p[k])));
}
ui.objectiveKey = null;
function drawObjectives() {
  fillObjectives();
  ui.objectivesOn = $("show-objectives").checked;
  $("objective").classList.toggle("hidden", !ui.objectivesOn);
  $("centre").classList.toggle("with-objectives", ui.objectivesOn);
  if (!ui.objectivesOn) return;
  oResize();
  while (oGroup.children.length) oGroup.remove(oGroup.children[0]);
  const byName = new Map(objectiveChoices().map((c) => [c.name, c]));
  const chosen = [$("obj-x").value, $("obj-y").value, $("obj-z").value].filter((n) => n && byName.has(n));
  const axes = chosen.map((n) => byName.get(n));
  const rows = (ui.pcRows || []).filter((r) => r.valid);
  const points = [], ids = [];
  for (const r of rows) {
    const p = axes.map((c) => objective(c, r));
    if (p.every((v) => v !== null)) { points.push(p); ids.push(r); }
  }
  const front = nonDominated(points);
  const dims = axes.length;
  const ranges = axes.map((_, k) => extent(points.map((p) => p[k])));
  const at = (p) => new THREE.Vector3(...[0, 1, 2].map((k) => k < dims ? (p[k] - ranges[k][0]) / (ranges[k][1] - ranges[k][0]) * CUBE : 0));
  // the box and the axes' names and ends
  const box = new THREE.Box3Helper(new THREE.Box3(new THREE.Vector3(0, 0, 0), new THREE.Vector3(CUBE, CUBE, dims > 2 ? CUBE : 0)), 0x5b6578);
  box.material.transparent = true; box.material.opacity = 0.5; oGroup.add(box);
  const grid = new THREE.GridHelper(CUBE, 5, 0x2b3440, 0x1c232c);
  grid.rotation.x = Math.PI / 2; grid.position.set(CUBE / 2, CUBE / 2, 0); oGroup.add(grid);
  // each axis named along its side, with its range (low at the origin's end)
  const where = [new THREE.Vector3(CUBE / 2, -1.2, 0), new THREE.Vector3(-0.3, CUBE + 0.9, 0), new THREE.Vector3(-0.3, -0.3, CUBE + 0.8)];
  axes.forEach((c, k) => {
    const sprite = axisSprite(`${c.name.replace("_", " ")}  ${fmt(ranges[k][0], 3)} → ${fmt(ranges[k][1], 3)}`, ["#f2a541", "#59c3c3", "#9b8cf2"][k]);
    if (k) sprite.center.set(0, 0.5);   // y and z: from the axis rightwards, inside the view
    sprite.position.copy(where[k]); oGroup.add(sprite);
  });
  const frontMat = new THREE.MeshStandardMaterial({ color: 0xf2a541, emissive: 0xf2a541, emissiveIntensity: 0.35 });
  const restMat = new THREE.MeshStandardMaterial({ color: 0x4f9de0, transparent: true, opacity: 0.8 });
  const outMat = new THREE.MeshStandardMaterial({ color: 0x4f9de0, transparent: true, opacity: 0.15 });
  const big = new THREE.SphereGeometry(0.24, 16, 12), small = new THREE.SphereGeometry(0.15, 12, 8);
  ui.objectivePoints = new Map();
  points.forEach((p, i) => {
    const r = ids[i], inside = !ui.brushes.size || brushed(r);
    const m = new THREE.Mesh(front[i] ? big : small, front[i] ? frontMat : inside ? restMat : outMat);
    m.position.copy(at(p)); m.userData.id = r.id; oGroup.add(m);
    ui.objectivePoints.set(r.id, m);
  });
  if (dims === 2) {   // the front as a staircase through its points
    const f = points.filter((_, i) => front[i]).sort((a, b) => a[0] - b[0]);
    const stairs = [];
    f.forEach((p, i) => { const q = at(p); if (i) stairs.push(new THREE.Vector3(q.x, stairs[stairs.length - 1].y, 0.01)); stairs.push(q.setZ(0.01)); });
    if (stairs.length > 1) oGroup.add(new THREE.Line(new THREE.BufferGeometry().setFromPoints(stairs), new THREE.LineBasicMaterial({ color: 0xf2a541, transparent: true, opacity: 0.6 })));
  }
  markObjective();
  const count = front.filter(Boolean).length;
  $("obj-count").textContent = `${count} of ${points.length} non-dominated`;
  document.body.dataset.objectivePoints = String(points.length);
  document.body.dataset.objectiveFront = String(count);
  document.body.dataset.objectiveFrontIds = ids.filter((_, i) => front[i]).map((r) => r.id).join(" ");
  const key = chosen.join("|");
  if (key !== ui.objectiveKey) {   // new axes: framed again; otherwise the designer's view is kept
    ui.objectiveKey = key;
    const c = new THREE.Vector3(CUBE / 2, CUBE / 2, dims > 2 ? CUBE / 2 : 0);
    const radius = (dims > 2 ? 0.87 : 0.71) * CUBE + 4;   // the box and its labels
    const distance = radius / Math.sin(THREE.MathUtils.degToRad(oCamera.fov / 2)) / Math.min(1, oCamera.aspect);
    oControls.target.copy(c);
    oCamera.position.copy(c).add((dims > 2 ? new THREE.Vector3(0.5, -0.75, 0.45) : new THREE.Vector3(0, -0.25, 1)).normalize().multiplyScalar(distance));
    oCamera.updateProjectionMatrix();
  }
}
function axisSprite(text, colour) {   // a label as wide as its text, 1 unit high
  const c = document.createElement("canvas"), g = c.getContext("2d"), font = "600 40px ui-monospace, monospace";
  g.font = font; c.width = Math.ceil(g.measureText(text).width) + 28; c.height = 60;
  g.fillStyle = "rgba(14,17,22,0.8)"; g.beginPath(); g.roundRect(0, 0, c.width, 60, 14); g.fill();
  g.font = font; g.fillStyle = colour; g.textBaseline = "middle"; g.fillText(text, 14, 31);
  const sprite = new THREE.Sprite(new THREE.SpriteMaterial({ map: new THREE.CanvasTexture(c), depthTest: false, transparent: true }));
  sprite.scale.set(c.width / 60, 1, 1); sprite.renderOrder = 10;
  return sprite;
}
let objMarker = null;
function markObjective() {
  if (objMarker) { oGroup.remove(objMarker); objMarker = null; }
  const m = ui.objectivePoints && ui.objectivePoints.get(ui.selected);
  if (!m) return;
  objMarker = new THREE.Mesh(new THREE.SphereGeometry(0.42, 20, 14), new THREE.MeshBasicMaterial({ color: 0xffffff, wireframe: true }));
  objMarker.position.copy(m.position); oGroup.add(objMarker);
}
// a click (a press that did not drag) on a point: its design selected, and its surface shown
const oRay = new THREE.Raycaster(); let oPressed = null;
oRenderer.domElement.addEventListener("pointerdown", (e) => { oPressed = [e.clientX, e.clientY]; });
oRenderer.domElement.addEventListener("pointerup", (e) => {
  if (!oPressed || Math.hypot(e.clientX - oPressed[0], e.clientY - oPressed[1]) > 4) return;
  const r = oRenderer.domElement.getBoundingClientRect();
  oRay.setFromCamera(new THREE.Vector2((e.clientX - r.left) / r.width * 2 - 1, -(e.clientY - r.top) / r.height * 2 + 1), oCamera);
  const hit = oRay.intersectObjects([...(ui.objectivePoints || new Map()).values()], false)[0];
  if (hit) showDesign(hit.object.userData.id);
});
// select a design and make sure its surface is among those in the 3D view
function showDesign(id) {
  select(id);
  if (!ui.designs.has(id) && !(ui.order || []).includes(id)) {
    showDesigns([id, ...(ui.order || []).filter((x) => x !== id)].slice(0, Math.max((ui.order || []).length, 1)), ui.pcRows || []);
  }
}
ui.showDesign = showDesign;
// where the point of design id is drawn, in page coordinates (read by the browser test)
ui.objectiveAt = (id) => {
  const m = ui.objectivePoints && ui.objectivePoints.get(id);
  if (!m) return null;
  const v = m.position.clone().project(oCamera), r = oRenderer.domElement.getBoundingClientRect();
  return [r.left + (v.x + 1) / 2 * r.width, r.top + (1 - v.y) / 2 * r.height];
};
for (const id of ["obj-x", "obj-y", "obj-z"]) $(id).onchange = drawObjectives;
$("show-objectives").onchange = () => { drawObjectives(); resize(); frameAll(); };

// ------------------------------------------------------------------------------------------ design
async function select(id) {
  ui.selected = id;
  document.querySelectorAll("#pc path.design").forEach((n) => n.classList.toggle("selected", n.dataset.id === id));
  markObjective();
  document.querySelectorAll("#gen-list [data-id], #kinds-list [data-id]").forEach((n) => n.classList.toggle("selected", n.dataset.id === id));
  highlight();
  let d;
  try { d = await getJSON(`/api/individual?id=${id}`); } catch (e) { toast(e.message, true); return; }
  if (ui.selected !== id) return;
  $("design-empty").classList.add("hidden"); $("design").classList.remove("hidden");
  $("d-id").textContent = d.id;
  $("d-fitness").textContent = fmt(d.fitness, 4);
  const parents = d.parents.length ? ` of ${d.parents.join(" × ")}` : "";
  $("d-origin").textContent = `island ${d.island} · generation ${d.generation} · ${d.origin}${parents} · config v${d.config_version}` +
    (d.hand_fitness.length ? ` · hand fitness ${d.hand_fitness.map((h) => fmt(h.fitness, 3)).join(", ")}` : "") +
    (d.durable === false ? " · not yet committed" : "");
  $("hand-value").value = d.fitness !== null ? Number(d.fitness).toPrecision(4) : "";
  const maxDev = Math.max(1e-9, ...d.criteria.map((c) => c.weight && c.value !== null && c.target !== null ? c.weight * Math.abs(c.value - c.target) : 0));
  $("d-criteria").innerHTML = `<tr><th>criterion</th><th style="text-align:right">value</th><th style="text-align:right">target</th><th style="text-align:right">weight</th><th></th></tr>` +
    d.criteria.map((c) => {
      const dev = c.weight && c.value !== null && c.target !== null ? c.weight * Math.abs(c.value - c.target) : 0;
      return `<tr><th>${c.name.replace("_", " ")}</th><td>${fmt(c.value, 3)}</td><td>${fmt(c.target, 3)}</td><td>${fmt(c.weight, 3)}</td>` +
        `<td class="dev"><div class="devbar" style="width:${(100 * dev / maxDev).toFixed(0)}%"></div></td></tr>`;
    }).join("");
  $("d-downloads").innerHTML = "Download" + d.downloads.map((f) => `<a download href="/api/download?id=${d.id}&format=${f.format}">${f.label}</a>`).join("");
  $("d-lineage").innerHTML = d.lineage.map((r) => `<li data-id="${r.id}">${r.id}<span>${r.origin}</span>${fmt(r.fitness, 3)}</li>`).join("");
  $("d-text").textContent = d.text || `(no rewrite system: failed at ${d.stage}: ${d.error})`;
  document.body.dataset.selected = id;
}
$("d-lineage").addEventListener("click", (e) => { const row = e.target.closest("[data-id]"); if (row) select(row.dataset.id); });
$("favour").onclick = () => ui.selected && act({ action: "favour", ids: [ui.selected] });
$("hand-set").onclick = () => {
  const v = Number($("hand-value").value);
  if (!ui.selected || $("hand-value").value === "" || !isFinite(v)) { toast("type a fitness (a number >= 0, lower is better)", true); return; }
  act({ action: "hand_fitness", id: ui.selected, fitness: v });
};

// ------------------------------------------------------------------------------------------- steer
let steerFilled = false;
function fillSteer(s) {
  if (steerFilled) return;
  steerFilled = true;
  $("weights").innerHTML = `<thead><tr><th>criterion</th><th>target</th><th>weight</th></tr></thead>` + s.criteria.map((c) =>
    `<tr><th>${c.name.replace("_", " ")}</th><td><input data-key="fitness.${c.name}.target" value="${c.target ?? ""}"></td>` +
    `<td><input data-key="fitness.${c.name}.weight" value="${c.weight ?? ""}"></td></tr>`).join("");
  $("weights").querySelectorAll("input").forEach((i) => { i.dataset.was = i.value; });
  $("env-gravity").value = JSON.stringify(s.environment.gravity);
  $("env-scale").value = JSON.stringify(s.environment.scale);
  $("env-gravity").dataset.was = $("env-gravity").value; $("env-scale").dataset.was = $("env-scale").value;
  $("inject").disabled = !s.injectable;
  if (!s.injectable) $("inject").title = "the run's universe is a plugin: the studio runs no plugin code";
}
$("apply-weights").onclick = async () => {
  const changed = [...$("weights").querySelectorAll("input")].filter((i) => i.value !== i.dataset.was && i.value !== "");
  if (!changed.length) { toast("change a target or a weight first", true); return; }
  if (await act({ action: "set", assignments: changed.map((i) => `${i.dataset.key}=${i.value}`) })) changed.forEach((i) => { i.dataset.was = i.value; });
};
$("apply-env").onclick = () => {
  const a = [];
  for (const [id, key] of [["env-gravity", "environment.gravity"], ["env-scale", "environment.scale"]]) {
    const i = $(id); if (i.value && i.value !== i.dataset.was) a.push(`${key}=${i.value}`);
  }
  if ($("env-other").value.trim()) a.push($("env-other").value.trim());
  if (!a.length) { toast("change the environment first", true); return; }
  act({ action: "set", assignments: a });
};
$("inject").onclick = () => act({ action: "inject", text: $("inject-text").value, island: $("inject-island").value });
$("add-generations").onclick = () => act({ action: "generations", generations: Number($("more").value) });
$("pause").onclick = () => act({ action: ui.state && ui.state.status === "paused" ? "continue" : "pause" });
document.querySelectorAll(".tabs button").forEach((b) => b.onclick = () => {
  document.querySelectorAll(".tabs button").forEach((x) => x.classList.toggle("active", x === b));
  $("tab-design").classList.toggle("hidden", b.dataset.tab !== "design");
  $("tab-steer").classList.toggle("hidden", b.dataset.tab !== "steer");
});

// -------------------------------------------------------------------------------------------- poll
let polling = false;
async function poll() {
  if (polling) return;
  polling = true;
  try {
    const s = await getJSON("/api/state");
    ui.state = s;
    showState(s);
    // the newest generation every island completed (before its commit), else the founders so far
    const target = (s.completed ?? s.generation) >= 0 ? (s.completed ?? s.generation) : ((s.live && s.live.generations.includes(0)) ? 0 : -1);
    const reached = (g) => s.islands.filter((i) => Math.max(i.completed ?? -1, i.generation) >= g).length;
    const stale = ui.generation && ui.generation.durable === false &&
      (s.version !== ui.version || (ui.generation.islands || []).length < reached(ui.viewGen));
    if (target >= 0 && (ui.viewGen < 0 || (ui.follow && target !== ui.viewGen))) loadGeneration(target);
    else if (stale) loadGeneration(ui.viewGen);
    const liveCurves = (s.completed ?? -1) > (curves ? curves.last : -1);
    if (s.version !== ui.version || liveCurves) {
      ui.version = s.version;
      // the generation's designs first (a few files), the curves apart (the whole run, once)
      const asked = s.version;
      getJSON("/api/curves").then((c) => { if (!curves || c.last >= curves.last || c.live < curves.live) { curves = c; drawCurves(); } })
        .catch(() => { if (ui.version === asked) ui.version = -1; });   // asked again at the next poll
    }
  } catch (e) {
    $("status").textContent = e.message.includes("not a run") || e.message.includes("no such run") ? "starting" : "waiting";
    $("status").className = "pill stopped";
  } finally { polling = false; }
}
poll();
setInterval(poll, 1000);
