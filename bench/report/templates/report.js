// levelset-bench report: sortable / foldable summary tables, the 3-D mesh viewer, the charts. No network.
(function () {
  "use strict";
  var KEY = ["method", "status", "hausdorff_h", "hausdorff_95_h", "hausdorff_90_h", "mean_dist_h", "normal_consistency",
             "fscore@h", "sdf_rms_h", "phi_mean_h", "sign_err_pct", "roughness_deg", "self_intersections", "euler",
             "components", "iou", "wall_s"];
  var meshesCache = null;
  function allMeshes() {   // parsed on the first click, not while the page loads
    if (meshesCache === null) meshesCache = JSON.parse(document.getElementById("lsb-meshes").textContent || "{}");
    return meshesCache;
  }
  window.lsbDrawn = {charts: 0, viewers: 0, chartsDoneMs: null};

  function cellValue(td) {
    var t = td.textContent.trim().replace(/[−]/g, "-");
    var x = parseFloat(t);
    return isNaN(x) ? t : x;
  }
  function sortBy(table, col) {
    var body = table.tBodies[0], rows = Array.prototype.slice.call(body.rows);
    var dir = table.getAttribute("data-sort") === String(col) ? -1 : 1;
    table.setAttribute("data-sort", dir === 1 ? String(col) : "");
    rows.sort(function (a, b) {
      var x = cellValue(a.cells[col]), y = cellValue(b.cells[col]);
      if (typeof x === "number" && typeof y === "number") return dir * (x - y);
      if (typeof x === "number") return -1;
      if (typeof y === "number") return 1;
      return dir * String(x).localeCompare(String(y));
    });
    rows.forEach(function (r) { body.appendChild(r); });
  }
  function fold(table, folded) {
    var heads = table.tHead.rows[0].cells;
    for (var c = 0; c < heads.length; c++) {
      var hide = folded && KEY.indexOf(heads[c].textContent.trim()) < 0;
      heads[c].classList.toggle("folded", hide);
      for (var r = 0; r < table.tBodies[0].rows.length; r++) {
        var cell = table.tBodies[0].rows[r].cells[c];
        if (cell) cell.classList.toggle("folded", hide);
      }
    }
  }
  function reorder(table) {   // key columns first, in KEY order, the rest after them
    var heads = Array.prototype.map.call(table.tHead.rows[0].cells, function (h) { return h.textContent.trim(); });
    var order = heads.map(function (h, i) { return i; });
    order.sort(function (a, b) {
      var ka = KEY.indexOf(heads[a]), kb = KEY.indexOf(heads[b]);
      ka = ka < 0 ? 1000 + a : ka; kb = kb < 0 ? 1000 + b : kb;
      return ka - kb;
    });
    Array.prototype.forEach.call(table.rows, function (row) {
      var cells = Array.prototype.slice.call(row.cells);
      order.forEach(function (i) { row.appendChild(cells[i]); });
    });
  }
  function bytes(b64) {
    var s = atob(b64), out = new Uint8Array(s.length);
    for (var i = 0; i < s.length; i++) out[i] = s.charCodeAt(i);
    return out;
  }
  function unpack(m) {   // uint16 vertices over their box, uint16/uint32 faces, uint8 colours over the range
    if (m.x) return m;
    var q = new Uint16Array(bytes(m.v).buffer), n = m.n, x = new Float32Array(n), y = new Float32Array(n),
        z = new Float32Array(n), f = m.f32 ? new Uint32Array(bytes(m.f).buffer) : new Uint16Array(bytes(m.f).buffer);
    var d = [x, y, z];
    for (var a = 0; a < 3; a++) {
      var lo = m.lo[a], sp = (m.hi[a] > m.lo[a] ? m.hi[a] - m.lo[a] : 1) / 65535;
      for (var p = 0; p < n; p++) d[a][p] = lo + sp * q[3 * p + a];
    }
    var i = new Uint32Array(m.nf), j = new Uint32Array(m.nf), k = new Uint32Array(m.nf);
    for (var t = 0; t < m.nf; t++) { i[t] = f[3 * t]; j[t] = f[3 * t + 1]; k[t] = f[3 * t + 2]; }
    m.x = x; m.y = y; m.z = z; m.i = i; m.j = j; m.k = k;
    return m;
  }
  function colours(m, what, range) {
    if (!m[what] || !range) return null;
    var q = bytes(m[what]), out = new Float32Array(q.length), sp = (range[1] - range[0]) / 255;
    for (var p = 0; p < q.length; p++) out[p] = range[0] + sp * q[p];
    return out;
  }
  var colourBy = document.getElementById("viewer-colour"), current = null;
  function drawViewer(cid, group, title) {
    var meshes = allMeshes(), m = meshes.cells ? meshes.cells[cid] : null;
    var panel = document.getElementById("viewer-panel");
    if (!m) { panel.hidden = false; document.getElementById("viewer-title").textContent =
        title + ": " + (meshes.note || "no mesh stored for this cell"); Plotly.purge("viewer"); return; }
    current = {cid: cid, group: group, title: title};
    unpack(m);
    var what = colourBy.value, use = m[what] ? what : "H";
    var range = ((meshes.ranges || {})[group] || {})[use] || null, values = colours(m, use, range);
    var trace = {type: "mesh3d", x: m.x, y: m.y, z: m.z, i: m.i, j: m.j, k: m.k, flatshading: true,
                 hoverinfo: "skip"};
    if (values) {
      trace.intensity = values; trace.showscale = true;
      trace.colorscale = what === "d" && m.d ? "RdBu" : "Jet"; trace.reversescale = what === "d" && !!m.d;
      if (range) { trace.cmin = range[0]; trace.cmax = range[1]; }
      trace.colorbar = {title: {text: what === "d" && m.d ? "d / h" : "H"}};
    } else { trace.color = "#9ab"; }
    panel.hidden = false;
    document.getElementById("viewer-title").textContent = title + " (" + m.nf + " of " + m.faces_full +
      " faces shown)" + (what === "d" && !m.d ? " — no truth: coloured by H" : "");
    Plotly.react("viewer", [trace], {margin: {l: 0, r: 0, t: 0, b: 0}, scene: {aspectmode: "data"}},
                 {responsive: true}).then(function () { window.lsbDrawn.viewers += 1; });
  }
  colourBy.addEventListener("change", function () { if (current) drawViewer(current.cid, current.group, current.title); });
  document.getElementById("viewer-close").addEventListener("click", function () {
    document.getElementById("viewer-panel").hidden = true; current = null; });
  var folded = true;
  Array.prototype.forEach.call(document.querySelectorAll(".summary-wrap"), function (wrap) {
    var table = wrap.querySelector("table"), cells = JSON.parse(wrap.getAttribute("data-cells") || "{}");
    var group = wrap.getAttribute("data-group");
    var title = wrap.previousElementSibling ? wrap.previousElementSibling.textContent : "";
    if (!table || !table.tHead) return;
    reorder(table);
    fold(table, true);
    Array.prototype.forEach.call(table.tHead.rows[0].cells, function (th, col) {
      th.title = "sort"; th.addEventListener("click", function () { sortBy(table, col); });
    });
    Array.prototype.forEach.call(table.tBodies[0].rows, function (tr) {
      var label = tr.cells[0].textContent.trim(), cid = cells[label];
      if (!cid) return;
      tr.setAttribute("data-cell", cid);
      tr.title = "show " + cid + " in 3-D";
      tr.addEventListener("click", function () { drawViewer(cid, group, title + " — " + label); });
    });
  });
  var unfold = document.getElementById("unfold");
  if (unfold) unfold.addEventListener("click", function () {
    folded = !folded;
    Array.prototype.forEach.call(document.querySelectorAll("table.summary"), function (t) { fold(t, folded); });
    unfold.textContent = folded ? "show all columns" : "key columns only";
  });
  function drawCharts() {   // after the load event: the tables are usable first, the charts follow at once
    var charts = JSON.parse(document.getElementById("lsb-charts").textContent || "[]");
    charts.forEach(function (fig, i) {
      Plotly.newPlot("chart-" + (i + 1), fig.data, fig.layout, {responsive: true}).then(function () {
        window.lsbDrawn.charts += 1;
        if (window.lsbDrawn.charts === charts.length) window.lsbDrawn.chartsDoneMs = performance.now();
      });
    });
  }
  if (document.readyState === "complete") drawCharts();
  else window.addEventListener("load", function () { setTimeout(drawCharts, 0); });
})();
