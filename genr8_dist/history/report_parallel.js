// genr8 report's side of the studio's parallel.js (inlined after it): its rows and axes from the
// page's JSON, and the table of the designs inside every brush, best first.
(function () {
  const data = JSON.parse(document.getElementById("pc-data").textContent);
  const svg = document.getElementById("pc"), list = document.getElementById("pc-list");
  const count = document.getElementById("pc-count");
  const axes = [{ key: "fitness", label: "fitness", get: (r) => r.fitness, target: null },
    ...data.axes.map((a) => ({ key: a.key, label: a.label, get: (r) => r.criteria[a.key], target: a.target }))];
  const brushes = new Map();
  let selected = null;
  const mix = (t) => {
    const a = [242, 165, 65], b = [79, 157, 224];
    return `rgb(${a.map((v, i) => Math.round(v + (b[i] - v) * t)).join(",")})`;
  };
  const cell = (v) => v === null || v === undefined ? "–" : Number(v).toPrecision(4).replace(/\.?0+(e|$)/, "$1");
  function table() {
    const inside = data.rows.filter((r) => !brushes.size || inBrushes(r, axes, brushes));
    count.textContent = brushes.size ? `${inside.length} of ${data.rows.length} designs brushed`
      : `${data.rows.length} designs`;
    document.body.dataset.brushed = String(inside.length);
    list.innerHTML = "<tr><th>id</th><th>gen</th><th>island</th>" +
      axes.map((a) => `<th>${a.label}</th>`).join("") + "</tr>" +
      inside.slice(0, 50).map((r) => `<tr data-id="${r.id}" class="${r.id === selected ? "picked" : ""}">` +
        `<td><code>${r.id}</code></td><td class="num">${r.generation}</td><td class="num">${r.island}</td>` +
        axes.map((a) => `<td class="num">${cell(a.get(r))}</td>`).join("") + "</tr>").join("") +
      (inside.length > 50 ? `<tr><td colspan="${axes.length + 3}" class="note">… and ${inside.length - 50} more</td></tr>` : "");
  }
  function draw() {
    drawParallel(svg, { rows: data.rows, axes, brushes, selected,
      colour: (rank, n) => mix(n > 1 ? rank / (n - 1) : 0),
      onSelect: (id) => { selected = id; draw(); table(); },
      onBrushEnd: table });
  }
  document.getElementById("pc-clear").onclick = () => { brushes.clear(); draw(); table(); };
  window.addEventListener("resize", draw);
  draw(); table();
})();
