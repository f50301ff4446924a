// tipgeo report: the page's links between plots (no network, no globals but tipgeoReport).
(function () {
  "use strict";
  var links = JSON.parse(document.getElementById("tg-links").textContent);
  function el(id) { return document.getElementById(id); }
  function arr(gd, trace, key) {
    var t = (gd._fullData && gd._fullData[trace]) || gd.data[trace];
    return t[key];
  }
  var api = { links: links, errors: [] };
  window.tipgeoReport = api;

  // hover on an angle plot: mark the same point on the 3D edge
  function edgeHover(L) {
    var src = el(L.src), dst = el(L.dst);
    if (!src || !dst) return;
    src.on("plotly_hover", function (e) {
      var p = e.points && e.points[0];
      if (!p || p.customdata === undefined || p.data.meta === undefined) return;
      var tr = p.data.meta, i = p.customdata;
      var x = arr(dst, tr, "x"), y = arr(dst, tr, "y"), z = arr(dst, tr, "z");
      Plotly.restyle(dst, { x: [[x[i]]], y: [[y[i]]], z: [[z[i]]] }, [L.marker]);
      var r = el(L.readout);
      if (r) r.textContent = p.data.name + ": γ " + Number(arr(dst, tr, "customdata")[i]).toFixed(2)
        + "°, point (" + [x[i], y[i], z[i]].map(function (v) { return Number(v).toFixed(4); }).join(", ")
        + ") mm";
    });
  }

  // a program's moves played through by a slider (and a play button)
  function toolpath(L) {
    var gd = el(L.div), s = el(L.slider), play = el(L.play), out = el(L.readout);
    if (!gd || !s) return;
    var P = L.path, n = P.x.length - 1, timer = null;
    function show(k) {
      k = Math.max(0, Math.min(n, k | 0));
      var cut = k + 1;
      Plotly.restyle(gd, { x: [P.x.slice(0, cut), [P.x[k]]], y: [P.y.slice(0, cut), [P.y[k]]],
                           z: [P.z.slice(0, cut), [P.z[k]]] }, [L.done, L.marker]);
      if (out) out.textContent = "move " + k + " of " + n + (k > 0 ? " (" + P.names[P.kind[k - 1]] + ")" : " (start)")
        + ", " + (L.label || "tool tip") + " (" + [P.x[k], P.y[k], P.z[k]].map(function (v) { return v.toFixed(4); }).join(", ") + ") mm";
    }
    s.addEventListener("input", function () { show(+s.value); });
    if (play) play.addEventListener("click", function () {
      if (timer) { clearInterval(timer); timer = null; play.textContent = "▶ play"; return; }
      if (+s.value >= n) s.value = 0;
      play.textContent = "❚❚ pause";
      var step = Math.max(1, Math.round(n / 400));
      timer = setInterval(function () {
        var k = Math.min(n, +s.value + step);
        s.value = k; show(k);
        if (k >= n) { clearInterval(timer); timer = null; play.textContent = "▶ play"; }
      }, 40);
    });
    show(+s.value);
  }

  // click a histogram bar: its displayed points shown on the cloud
  function histPick(L) {
    var h = el(L.hist), c = el(L.cloud), out = el(L.readout);
    if (!h || !c) return;
    function pick(lo, hi, count) {
      var x = arr(c, L.src, "x"), y = arr(c, L.src, "y"), z = arr(c, L.src, "z");
      var d = arr(c, L.src, "marker").color, sx = [], sy = [], sz = [];
      for (var i = 0; i < d.length; i++) {
        if (d[i] >= lo && d[i] < hi) { sx.push(x[i]); sy.push(y[i]); sz.push(z[i]); }
      }
      Plotly.restyle(c, { x: [sx], y: [sy], z: [sz] }, [L.sel]);
      if (out) out.textContent = "deviation " + lo.toFixed(2) + " … " + hi.toFixed(2) + " µm: "
        + count + " points of the scan, " + sx.length + " of them displayed (black)";
      return sx.length;
    }
    api.pick = pick;
    h.on("plotly_click", function (e) {
      var p = e.points && e.points[0];
      if (!p || !p.customdata) return;
      pick(p.customdata[0], p.customdata[1], p.customdata[2]);
    });
  }

  var kinds = { "edge-hover": edgeHover, "toolpath": toolpath, "hist-pick": histPick };
  links.forEach(function (L) {
    try { kinds[L.kind](L); } catch (err) { api.errors.push(String(err)); console.error(err); }
  });
})();
