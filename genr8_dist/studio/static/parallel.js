// Parallel coordinates of the criteria (Wallacei's view), shared by the studio and `genr8 report`
// (which inlines this file): every design as a line across its axes (raw values; a target marked on
// its axis). Dragging along an axis brushes a range; a click on an axis clears its brush; the designs
// inside every brush are "brushed". A click on a line selects its design. Plain SVG, no library.
const SVGNS = "http://www.w3.org/2000/svg";
// an SVG element `name` with `attrs`, appended to `parent` when given (the studio's charts use it too)
export function node(name, attrs, parent) {
  const e = document.createElementNS(SVGNS, name);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
  if (parent) parent.appendChild(e);
  return e;
}
const short = (v) => (v === null || v === undefined || !Number.isFinite(v)) ? "–" :
  Math.abs(v) < 1e-9 ? "0" : Number(v).toPrecision(3).replace(/\.?0+(e|$)/, "$1");

// whether row r lies inside every brush (brushes: Map axis key -> [lo, hi]; axes: {key, get})
export function inBrushes(r, axes, brushes) {
  for (const [key, [lo, hi]] of brushes) {
    const axis = axes.find((a) => a.key === key);
    const v = axis ? axis.get(r) : null;
    if (v === null || v === undefined || !Number.isFinite(v) || v < lo || v > hi) return false;
  }
  return true;
}

// Draw into svg. opts: rows (best first), axes [{key, label, get(row), target}], brushes (a Map,
// changed in place while dragging), selected (an id), colour(rank, count) -> CSS colour,
// onSelect(id), onDraw(brushed) (after every drawing, a drag's too), onBrushEnd() (after a drag or a
// click on an axis). Returns how many rows are brushed.
export function drawParallel(svg, opts) {
  const { rows, axes, brushes } = opts;
  svg.innerHTML = "";
  const W = svg.clientWidth || 800, H = svg.clientHeight || 196, top = 22, bottom = H - 16;
  const xs = axes.map((_, i) => 60 + i * (W - 120) / Math.max(1, axes.length - 1));
  const scales = axes.map((a) => {
    const vs = rows.map(a.get).filter((v) => v !== null && v !== undefined && Number.isFinite(v));
    if (a.target !== null && a.target !== undefined) vs.push(a.target);
    let lo = Math.min(...vs), hi = Math.max(...vs);
    if (!vs.length) { lo = 0; hi = 1; }
    if (hi - lo < 1e-12) { lo -= 0.5; hi += 0.5; }
    return { lo, hi, y: (v) => bottom - (v - lo) / (hi - lo) * (bottom - top), v: (y) => lo + (bottom - y) / (bottom - top) * (hi - lo) };
  });
  let inside = 0;
  const lines = node("g", {}, svg);
  rows.forEach((r, rank) => {
    const pts = axes.map((a, i) => { const v = a.get(r); return v === null || v === undefined || !Number.isFinite(v) ? null : [xs[i], scales[i].y(v)]; });
    const d = pts.map((p, i) => p ? `${i && pts[i - 1] ? "L" : "M"}${p[0].toFixed(1)},${p[1].toFixed(1)}` : "").join("");
    const ok = !brushes.size || inBrushes(r, axes, brushes);
    inside += ok ? 1 : 0;
    const line = node("path", { d, class: `design${ok ? "" : " out"}${r.id === opts.selected ? " selected" : ""}`,
      stroke: opts.colour(rank, rows.length), "data-id": r.id }, lines);
    node("title", {}, line).textContent = `${r.id} · fitness ${short(r.fitness)}`;
    line.addEventListener("click", () => opts.onSelect && opts.onSelect(r.id));
  });
  axes.forEach((a, i) => {
    const g = node("g", { class: "axis", "data-axis": a.key }, svg), sc = scales[i], x = xs[i];
    node("line", { x1: x, x2: x, y1: top, y2: bottom }, g);
    node("text", { x, y: 12, "text-anchor": "middle" }, g).textContent = a.label;
    node("text", { x: x + 4, y: top + 4, class: "tick" }, g).textContent = short(sc.hi);
    node("text", { x: x + 4, y: bottom, class: "tick" }, g).textContent = short(sc.lo);
    if (a.target !== null && a.target !== undefined) {
      const ty = sc.y(a.target);
      node("line", { x1: x - 7, x2: x + 7, y1: ty, y2: ty, class: "target" }, g);
    }
    const b = brushes.get(a.key);
    if (b) node("rect", { x: x - 8, width: 16, y: sc.y(b[1]), height: Math.max(2, sc.y(b[0]) - sc.y(b[1])), class: "brush" }, g);
    const hit = node("rect", { x: x - 14, width: 28, y: top - 4, height: bottom - top + 8, class: "hit" }, g);
    hit.addEventListener("mousedown", (ev) => {
      ev.preventDefault();
      const box = svg.getBoundingClientRect(), y0 = ev.clientY - box.top;
      let moved = false;
      const move = (e) => {
        const y1 = Math.max(top, Math.min(bottom, e.clientY - box.top)); moved = true;
        brushes.set(a.key, [Math.min(sc.v(y0), sc.v(y1)), Math.max(sc.v(y0), sc.v(y1))]);
        drawParallel(svg, opts);
      };
      const up = () => {
        window.removeEventListener("mousemove", move); window.removeEventListener("mouseup", up);
        if (!moved) brushes.delete(a.key);   // a click on an axis clears its brush
        if (opts.onBrushEnd) opts.onBrushEnd();
      };
      window.addEventListener("mousemove", move); window.addEventListener("mouseup", up);
    });
  });
  if (opts.onDraw) opts.onDraw(inside);
  return inside;
}
