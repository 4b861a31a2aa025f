/* The match report's viewer: win-probability timeline, key moments, rally player, what-if
   panel and statistics, drawn from the JSON document in #match-data with plain SVG and
   canvas (no library, nothing fetched). Court coordinates are the project's: metres, x along
   the court (baselines at +-11.885), y across, z up, origin at the centre of the net. */
(function () {
  "use strict";
  var D = JSON.parse(document.getElementById("match-data").textContent);
  var P = D.points;
  var N = P.point.length;
  var NAMES = D.players;
  var COLOURS = ["#d62728", "#1f77b4"];
  var SURFACE = { hard: "#3a6ea5", clay: "#c8643c", grass: "#4f8f3a" };
  var C = D.court;
  var SVGNS = "http://www.w3.org/2000/svg";
  var ui = { sel: -1, rally: null, frame: 0, playing: false, speed: 1, last: 0, acc: 0,
             whatif: -1 };

  // --- small helpers -------------------------------------------------------------------
  function el(tag, attrs, kids) {
    var e = document.createElement(tag);
    setAttrs(e, attrs);
    (kids || []).forEach(function (k) {
      e.appendChild(typeof k === "string" ? document.createTextNode(k) : k);
    });
    return e;
  }
  function sv(tag, attrs, parent) {
    var e = document.createElementNS(SVGNS, tag);
    setAttrs(e, attrs);
    if (parent) parent.appendChild(e);
    return e;
  }
  function setAttrs(e, attrs) {
    Object.keys(attrs || {}).forEach(function (k) {
      if (k === "text") e.textContent = attrs[k];
      else if (k === "cls") e.setAttribute("class", attrs[k]);
      else if (k.slice(0, 2) === "on") e.addEventListener(k.slice(2), attrs[k]);
      else e.setAttribute(k, attrs[k]);
    });
  }
  function pct(v, digits) {
    return v === null || v === undefined ? "-" : (100 * v).toFixed(digits === undefined ? 0 : digits) + "%";
  }
  function player(i) { return el("span", { cls: "p" + i, text: NAMES[i] }); }
  function words(s) { return String(s || "").replace(/_/g, " "); }
  function scoreText(i) {
    var g = P.games_p1[i] + "-" + P.games_p2[i];
    var s = P.point_score[i] === "0-0" && P.tag[i] !== "tie-break" ? g : g + " " + P.point_score[i];
    return "Set " + P.set_no[i] + ", " + s + (P.tag[i] && P.tag[i] !== "tie-break" ? " (" + P.tag[i] + ")" : "");
  }

  // --- header, footer ------------------------------------------------------------------
  function renderHeader() {
    var h = document.getElementById("head");
    h.appendChild(el("h1", { text: D.title }));
    h.appendChild(el("div", { cls: "score", text: D.score_line }));
    h.appendChild(el("div", { cls: "sub", text: D.subtitle }));
  }
  function renderFooter() {
    var f = document.getElementById("foot");
    f.appendChild(el("p", { text: D.model }));
    D.notes.forEach(function (n) { f.appendChild(el("p", { text: n })); });
    if (D.attribution) f.appendChild(el("p", { text: D.attribution }));
    if (D.stats.real_source) f.appendChild(el("p", { text: "2011 figures: " + D.stats.real_source + "." }));
    f.appendChild(el("p", { text: "Report written by sportsngen; self-contained, works offline." }));
  }

  // --- timeline ------------------------------------------------------------------------
  var TL = { w: 1000, h: 300, l: 48, r: 14, t: 24, b: 34 };
  TL.pw = TL.w - TL.l - TL.r;
  TL.ph = TL.h - TL.t - TL.b;
  function tx(i) { return TL.l + TL.pw * i / N; }
  function ty(p) { return TL.t + TL.ph * (1 - p); }
  var tlSvg, tlCursor, tlSel;

  function renderTimeline() {
    var box = document.getElementById("timeline");
    tlSvg = sv("svg", { viewBox: "0 0 " + TL.w + " " + TL.h, role: "img",
                        "aria-label": "win probability timeline" }, box);
    var maxImp = Math.max.apply(null, P.importance.concat([1e-9]));
    var shade = sv("g", {}, tlSvg);
    for (var i = 0; i < N; i++) {
      var a = 0.06 + 0.84 * P.importance[i] / maxImp;
      sv("rect", { x: tx(i), y: TL.t, width: Math.max(tx(i + 1) - tx(i), 0.5), height: TL.ph,
                   fill: "#ff9f1c", "fill-opacity": a.toFixed(3) }, shade);
    }
    var ax = sv("g", { cls: "axis" }, tlSvg);
    [0, 0.25, 0.5, 0.75, 1].forEach(function (p) {
      sv("line", { x1: TL.l, x2: TL.l + TL.pw, y1: ty(p), y2: ty(p),
                   stroke: p === 0.5 ? "#888" : "#ddd", "stroke-dasharray": p === 0.5 ? "4 3" : "" }, ax);
      sv("text", { x: TL.l - 6, y: ty(p) + 4, "text-anchor": "end", text: (100 * p) + "%" }, ax);
    });
    sv("text", { x: 12, y: TL.t + TL.ph / 2, transform: "rotate(-90 12 " + (TL.t + TL.ph / 2) + ")",
                 "text-anchor": "middle", cls: "lbl", text: "P(" + NAMES[0] + " wins)" }, tlSvg);
    for (i = 0; i < N; i++) {
      if (P.new_set[i]) {
        if (i > 0) sv("line", { x1: tx(i), x2: tx(i), y1: TL.t - 4, y2: TL.t + TL.ph, stroke: "#333",
                                "stroke-width": 1.4 }, tlSvg);
        sv("text", { x: tx(i) + 4, y: TL.t - 8, cls: "setlbl", text: "Set " + P.set_no[i] }, tlSvg);
      } else if (P.new_game[i]) {
        sv("line", { x1: tx(i), x2: tx(i), y1: TL.t + TL.ph, y2: TL.t + TL.ph + 6, stroke: "#999" }, tlSvg);
      }
    }
    sv("text", { x: TL.l + TL.pw / 2, y: TL.h - 4, "text-anchor": "middle", cls: "lbl",
                 text: "point (ticks: games; shading: importance of the point)" }, tlSvg);
    var pts = [];
    for (i = 0; i < N; i++) pts.push(tx(i).toFixed(1) + "," + ty(P.p_before[i]).toFixed(1));
    pts.push(tx(N).toFixed(1) + "," + ty(P.p_after[N - 1]).toFixed(1));
    sv("polyline", { points: pts.join(" "), fill: "none", stroke: COLOURS[0], "stroke-width": 1.8,
                     "stroke-linejoin": "round" }, tlSvg);
    var km = sv("g", { cls: "km" }, tlSvg);
    D.key_moments.forEach(function (m, k) {
      var x = (tx(m.i) + tx(m.i + 1)) / 2;
      var g = sv("g", { cls: "moment", "data-i": m.i }, km);
      sv("line", { x1: x, x2: x, y1: ty(P.p_before[m.i]), y2: ty(P.p_after[m.i]), stroke: "#000",
                   "stroke-width": 2 }, g);
      sv("circle", { cx: x, cy: ty(P.p_after[m.i]), r: 7, fill: "#fff", stroke: "#000",
                     "stroke-width": 1.5 }, g);
      sv("text", { x: x, y: ty(P.p_after[m.i]) + 4, "text-anchor": "middle", text: String(k + 1) }, g);
    });
    tlSel = sv("rect", { x: 0, y: TL.t, width: 0, height: TL.ph, fill: "none", stroke: "#000",
                         "stroke-width": 1.5, visibility: "hidden" }, tlSvg);
    tlCursor = sv("line", { y1: TL.t, y2: TL.t + TL.ph, stroke: "#000", "stroke-opacity": 0.35,
                            visibility: "hidden" }, tlSvg);
    tlSvg.addEventListener("mousemove", onTimelineMove);
    tlSvg.addEventListener("mouseleave", function () {
      tlCursor.setAttribute("visibility", "hidden");
      document.getElementById("tooltip").hidden = true;
    });
    tlSvg.addEventListener("click", function (ev) {
      var i = pointAt(ev);
      if (i >= 0) selectPoint(i);
    });
  }

  function pointAt(ev) {
    var pt = tlSvg.createSVGPoint();
    pt.x = ev.clientX;
    pt.y = ev.clientY;
    var p = pt.matrixTransform(tlSvg.getScreenCTM().inverse());
    var i = Math.floor((p.x - TL.l) / TL.pw * N);
    return i >= 0 && i < N ? i : -1;
  }

  function onTimelineMove(ev) {
    var i = pointAt(ev);
    var tip = document.getElementById("tooltip");
    if (i < 0) { tip.hidden = true; return; }
    var x = (tx(i) + tx(i + 1)) / 2;
    tlCursor.setAttribute("x1", x);
    tlCursor.setAttribute("x2", x);
    tlCursor.setAttribute("visibility", "visible");
    tip.innerHTML = "";
    tip.appendChild(el("div", { text: "Point " + P.point[i] + ": " + scoreText(i) }));
    tip.appendChild(el("div", { text: NAMES[P.server[i]] + " serving, " + NAMES[P.winner[i]] + " won it" }));
    tip.appendChild(el("div", { text: "P(" + NAMES[0] + " wins) " + pct(P.p_before[i]) + " \u2192 " +
                                      pct(P.p_after[i]) + ", importance " + P.importance[i].toFixed(3) }));
    tip.hidden = false;
    tip.style.left = (ev.pageX + 14) + "px";
    tip.style.top = (ev.pageY + 14) + "px";
  }

  function renderMoments() {
    var ol = document.getElementById("moments");
    D.key_moments.forEach(function (m) {
      ol.appendChild(el("li", { text: "Point " + P.point[m.i] + ". " + m.text,
                                onclick: function () { selectPoint(m.i); } }));
    });
  }

  // --- point panel ---------------------------------------------------------------------
  function selectPoint(i, rallyId) {
    ui.sel = i;
    tlSel.setAttribute("x", tx(i));
    tlSel.setAttribute("width", Math.max(tx(i + 1) - tx(i), 2));
    tlSel.setAttribute("visibility", "visible");
    var box = document.getElementById("point");
    box.innerHTML = "";
    var head = el("div", {}, ["Point " + P.point[i] + ": " + scoreText(i) + ". ", player(P.server[i]),
                              " serving; ", player(P.winner[i]), " won it."]);
    box.appendChild(head);
    var ifOther = P.winner[i] === 0 ? P.p_if_lost[i] : P.p_if_won[i];
    box.appendChild(el("div", { cls: "probs" }, [
      "P(" + NAMES[0] + " wins the match): ", el("b", { text: pct(P.p_before[i], 1) }), " before, ",
      el("b", { text: pct(P.p_after[i], 1) }), " after (", el("b", { text: pct(ifOther, 1) }),
      " had the point gone the other way). Importance ", el("b", { text: P.importance[i].toFixed(3) }), "."]));
    var ids = (P.rallies && P.rallies[i]) || [];
    if (!D.rallies || !ids.length) {
      stopPlaying();
      ui.rally = null;
      box.appendChild(el("p", { cls: "hint", text: D.rallies ? "No rally kept for this point." :
        "No tracking for this match: the report shows the score only." }));
      return;
    }
    var tabs = el("div", { cls: "tabs" });
    ids.forEach(function (id) {
      var r = D.rallies[String(id)];
      var label = (r.serve === 1 ? "1st serve" : "2nd serve") + (r.end_reason === "fault" ? " (fault)" : "");
      tabs.appendChild(el("button", { "data-rally": id, text: label,
                                      onclick: function () { showRally(id, 0, true); } }));
    });
    box.appendChild(tabs);
    box.appendChild(el("canvas", { id: "top", width: 960, height: 480 }));
    box.appendChild(el("canvas", { id: "side", width: 960, height: 170 }));
    var slider = el("input", { type: "range", min: 0, max: 1, value: 0, id: "scrub",
                               "aria-label": "rally frame" });
    slider.addEventListener("input", function () { stopPlaying(); ui.frame = +slider.value; drawRally(); });
    var speed = el("select", { id: "speed", "aria-label": "speed" });
    [["0.25", "0.25x"], ["0.5", "0.5x"], ["1", "1x"]].forEach(function (o) {
      speed.appendChild(el("option", { value: o[0], text: o[1] }));
    });
    speed.value = String(ui.speed);
    speed.addEventListener("change", function () { ui.speed = +speed.value; });
    box.appendChild(el("div", { cls: "controls" }, [
      el("button", { id: "play", text: "Pause", onclick: togglePlay }), slider, speed,
      el("span", { cls: "clock", id: "clock" })]));
    box.appendChild(el("div", { id: "rally-end", cls: "hint" }));
    box.appendChild(el("table", { cls: "shots", id: "shots" }));
    showRally(rallyId === undefined ? ids[ids.length - 1] : rallyId, 0, true);
  }

  function showRally(id, frame, play) {
    var r = D.rallies[String(id)];
    ui.rally = r;
    ui.frame = frame || 0;
    Array.prototype.forEach.call(document.querySelectorAll(".tabs button"), function (b) {
      b.classList.toggle("on", +b.getAttribute("data-rally") === r.id);
    });
    document.getElementById("scrub").max = r.n - 1;
    var end = words(r.end_reason) + (r.end_detail && r.end_detail !== "none" ? " (" + words(r.end_detail) + ")" : "");
    document.getElementById("rally-end").textContent = "Rally " + r.id + ": " + NAMES[r.server] +
      " serves from the " + r.side + " side; ends: " + end +
      (r.winner >= 0 ? ", point to " + NAMES[r.winner] : "") + ". Stars: contacts; crosses: bounces.";
    renderShots(r);
    drawRally();
    if (play) startPlaying(); else stopPlaying();
  }

  function renderShots(r) {
    var t = document.getElementById("shots");
    t.innerHTML = "";
    t.appendChild(el("tr", {}, ["#", "t (s)", "hitter", "stroke", "direction", "outcome", "km/h"].map(
      function (h) { return el("th", { text: h }); })));
    r.shots.forEach(function (s, k) {
      var wi = whatifIndex(r.id, k);
      var out = words(s.outcome) + (s.error && s.error !== "none" ? " (" + words(s.error) + ")" : "");
      var dirCell = el("td", { text: words(s.direction) });
      if (wi >= 0) dirCell.appendChild(el("span", { cls: "badge", text: "what if" }));
      var tr = el("tr", { cls: "clickable", "data-k": k, onclick: function () {
        stopPlaying();
        ui.frame = Math.max(0, s.f - 8);
        drawRally();
        if (wi >= 0) showWhatif(wi, false);
      } }, [el("td", { text: String(k + 1) }), el("td", { text: (s.f / D.fps).toFixed(2) }),
            el("td", {}, [player(s.hitter)]), el("td", { text: words(s.stroke) }), dirCell,
            el("td", { text: out }), el("td", { text: s.kmh === null ? "-" : String(s.kmh) })]);
      t.appendChild(tr);
    });
  }

  // --- rally drawing -------------------------------------------------------------------
  var TOP = { x0: -16.5, x1: 16.5, y0: -8.25, y1: 8.25 };
  var SIDE = { z0: -0.2, z1: 5.0 };
  function startPlaying() {
    ui.playing = true;
    ui.last = 0;
    document.getElementById("play").textContent = "Pause";
    requestAnimationFrame(tick);
  }
  function stopPlaying() {
    ui.playing = false;
    var b = document.getElementById("play");
    if (b) b.textContent = "Play";
  }
  function togglePlay() {
    if (ui.playing) { stopPlaying(); return; }
    if (ui.rally && ui.frame >= ui.rally.n - 1) ui.frame = 0;
    startPlaying();
  }
  function tick(now) {
    if (!ui.playing || !ui.rally) return;
    if (ui.last) ui.acc += (now - ui.last) / 1000 * D.fps * ui.speed;
    ui.last = now;
    var step = Math.floor(ui.acc);
    if (step > 0) {
      ui.acc -= step;
      ui.frame = Math.min(ui.frame + step, ui.rally.n - 1);
      drawRally();
    }
    if (ui.frame >= ui.rally.n - 1) { stopPlaying(); return; }
    requestAnimationFrame(tick);
  }

  function courtTop(ctx, w, h) {
    var sx = w / (TOP.x1 - TOP.x0), sy = h / (TOP.y1 - TOP.y0);
    function X(x) { return (x - TOP.x0) * sx; }
    function Y(y) { return (TOP.y1 - y) * sy; }
    var colour = SURFACE[D.surface] || SURFACE.hard;
    ctx.clearRect(0, 0, w, h);
    ctx.fillStyle = colour;
    ctx.globalAlpha = 0.45;
    ctx.fillRect(0, 0, w, h);
    ctx.globalAlpha = 1;
    ctx.fillRect(X(-C.baseline_x), Y(C.doubles_y), X(C.baseline_x) - X(-C.baseline_x), Y(-C.doubles_y) - Y(C.doubles_y));
    ctx.strokeStyle = "#fff";
    ctx.lineWidth = 2;
    function line(a, b, c, d) { ctx.beginPath(); ctx.moveTo(X(a), Y(b)); ctx.lineTo(X(c), Y(d)); ctx.stroke(); }
    [C.doubles_y, -C.doubles_y, C.singles_y, -C.singles_y].forEach(function (y) { line(-C.baseline_x, y, C.baseline_x, y); });
    [C.baseline_x, -C.baseline_x].forEach(function (x) { line(x, -C.doubles_y, x, C.doubles_y); line(x, 0, x - Math.sign(x) * 0.2, 0); });
    [C.service_x, -C.service_x].forEach(function (x) { line(x, -C.singles_y, x, C.singles_y); });
    line(-C.service_x, 0, C.service_x, 0);
    ctx.strokeStyle = "#222";
    ctx.lineWidth = 3;
    line(0, -C.net_post_y, 0, C.net_post_y);
    return { X: X, Y: Y };
  }
  function courtSide(ctx, w, h) {
    var sx = w / (TOP.x1 - TOP.x0), sz = h / (SIDE.z1 - SIDE.z0);
    function X(x) { return (x - TOP.x0) * sx; }
    function Z(z) { return (SIDE.z1 - z) * sz; }
    ctx.fillStyle = "#f3f6f9";
    ctx.fillRect(0, 0, w, h);
    ctx.strokeStyle = SURFACE[D.surface] || SURFACE.hard;
    ctx.lineWidth = 4;
    ctx.beginPath(); ctx.moveTo(X(-C.baseline_x), Z(0)); ctx.lineTo(X(C.baseline_x), Z(0)); ctx.stroke();
    ctx.strokeStyle = "#222";
    ctx.lineWidth = 3;
    ctx.beginPath(); ctx.moveTo(X(0), Z(0)); ctx.lineTo(X(0), Z(C.net_centre_z)); ctx.stroke();
    ctx.fillStyle = "#888";
    ctx.font = "12px sans-serif";
    ctx.fillText("side view: ball height (m) along the court", 8, 14);
    [1, 2, 3, 4].forEach(function (z) { ctx.fillText(z + " m", 4, Z(z) + 4); });
    return { X: X, Z: Z };
  }
  function star(ctx, x, y, r) {
    ctx.beginPath();
    for (var k = 0; k < 10; k++) {
      var a = Math.PI / 2 + k * Math.PI / 5, rr = k % 2 ? r * 0.45 : r;
      ctx.lineTo(x + rr * Math.cos(a), y - rr * Math.sin(a));
    }
    ctx.closePath();
    ctx.fillStyle = "#ffd400";
    ctx.fill();
    ctx.strokeStyle = "#000";
    ctx.lineWidth = 1;
    ctx.stroke();
  }
  function cross(ctx, x, y, r) {
    ctx.strokeStyle = "#000";
    ctx.lineWidth = 2.5;
    ctx.beginPath(); ctx.moveTo(x - r, y - r); ctx.lineTo(x + r, y + r);
    ctx.moveTo(x - r, y + r); ctx.lineTo(x + r, y - r); ctx.stroke();
  }

  function drawRally() {
    var r = ui.rally;
    if (!r) return;
    var f = Math.max(0, Math.min(ui.frame, r.n - 1));
    var B = r.ball;
    var top = document.getElementById("top"), side = document.getElementById("side");
    if (!top || !side) return;
    var ct = top.getContext("2d"), cs = side.getContext("2d");
    var T = courtTop(ct, top.width, top.height), S = courtSide(cs, side.width, side.height);
    var lo = Math.max(0, f - 15);
    // ball trail
    ct.strokeStyle = "rgba(255,240,0,0.9)"; ct.lineWidth = 2; ct.beginPath();
    cs.strokeStyle = "rgba(200,160,0,0.9)"; cs.lineWidth = 2; cs.beginPath();
    for (var k = lo; k <= f; k++) {
      var bx = B[3 * k] / 100, by = B[3 * k + 1] / 100, bz = B[3 * k + 2] / 100;
      if (k === lo) { ct.moveTo(T.X(bx), T.Y(by)); cs.moveTo(S.X(bx), S.Z(bz)); }
      else { ct.lineTo(T.X(bx), T.Y(by)); cs.lineTo(S.X(bx), S.Z(bz)); }
    }
    ct.stroke(); cs.stroke();
    r.bounces.forEach(function (b) {
      if (b[0] <= f) { cross(ct, T.X(b[1] / 100), T.Y(b[2] / 100), 6); cross(cs, S.X(b[1] / 100), S.Z(0), 5); }
    });
    var current = -1;
    r.shots.forEach(function (s, k) {
      if (s.f <= f) {
        current = k;
        star(ct, T.X(s.c[0] / 100), T.Y(s.c[1] / 100), 8);
        star(cs, S.X(s.c[0] / 100), S.Z(s.c[2] / 100), 7);
      }
    });
    [0, 1].forEach(function (p) {
      var px = r.p[p][2 * f] / 100, py = r.p[p][2 * f + 1] / 100;
      ct.beginPath(); ct.arc(T.X(px), T.Y(py), 10, 0, 2 * Math.PI);
      ct.fillStyle = COLOURS[p]; ct.fill(); ct.strokeStyle = "#fff"; ct.lineWidth = 2; ct.stroke();
      ct.fillStyle = "#fff"; ct.font = "bold 11px sans-serif"; ct.textAlign = "center";
      ct.fillText(NAMES[p].split(" ").map(function (w) { return w[0]; }).join("").slice(0, 2), T.X(px), T.Y(py) + 4);
      ct.textAlign = "left";
      cs.fillStyle = COLOURS[p];
      cs.fillRect(S.X(px) - 4, S.Z(1.85), 8, S.Z(0) - S.Z(1.85));
    });
    var x = B[3 * f] / 100, y = B[3 * f + 1] / 100, z = B[3 * f + 2] / 100;
    ct.beginPath(); ct.arc(T.X(x), T.Y(y), 3, 0, 2 * Math.PI); ct.fillStyle = "rgba(0,0,0,0.35)"; ct.fill();
    ct.beginPath(); ct.arc(T.X(x), T.Y(y) - 2 * z, 4 + 1.3 * Math.max(z, 0), 0, 2 * Math.PI);
    ct.fillStyle = "#fff200"; ct.fill(); ct.strokeStyle = "#000"; ct.lineWidth = 1; ct.stroke();
    cs.beginPath(); cs.arc(S.X(x), S.Z(z), 5, 0, 2 * Math.PI);
    cs.fillStyle = "#fff200"; cs.fill(); cs.strokeStyle = "#000"; cs.stroke();
    ct.fillStyle = "#fff"; ct.font = "13px sans-serif";
    ct.fillText("t = " + (f / D.fps).toFixed(2) + " s", 8, top.height - 10);
    document.getElementById("scrub").value = f;
    document.getElementById("clock").textContent = "frame " + f + " / " + (r.n - 1);
    Array.prototype.forEach.call(document.querySelectorAll("#shots tr[data-k]"), function (tr) {
      tr.classList.toggle("now", +tr.getAttribute("data-k") === current);
    });
  }

  // --- what if -------------------------------------------------------------------------
  function whatifIndex(rallyId, shot) {
    for (var k = 0; k < D.whatif.length; k++) {
      if (D.whatif[k].rally === rallyId && D.whatif[k].shot === shot) return k;
    }
    return -1;
  }
  function renderWhatifList() {
    var box = document.getElementById("whatif");
    if (!D.rallies) {  // a score-only report: no rallies to branch
      document.getElementById("whatif-section").hidden = true;
      return;
    }
    if (!D.whatif.length) {
      box.appendChild(el("p", { cls: "hint", text:
        "No what-if shots were computed for this report (simulate.py report_whatif_shots=N)." }));
      return;
    }
    box.appendChild(el("p", { cls: "hint", text: "Counterfactual shots, computed when the report was built: " +
      "the rally is branched just before the contact and the shot is forced each way." }));
    var list = el("div", { cls: "wi-list" });
    D.whatif.forEach(function (w, k) {
      list.appendChild(el("button", { "data-k": k, onclick: function () { showWhatif(k, true); },
        text: "Point " + w.point + ", shot " + (w.shot + 1) + ": " + NAMES[w.hitter] + " " + words(w.stroke) +
              " (" + words(w.played) + ", " + words(w.outcome) + ")" }));
    });
    box.appendChild(list);
    box.appendChild(el("div", { id: "whatif-chart" }));
  }
  function showWhatif(k, open) {
    var w = D.whatif[k];
    ui.whatif = k;
    Array.prototype.forEach.call(document.querySelectorAll(".wi-list button"), function (b) {
      b.classList.toggle("on", +b.getAttribute("data-k") === k);
    });
    if (open) {
      selectPoint(w.row, w.rally);
      stopPlaying();
      var s = D.rallies[String(w.rally)].shots[w.shot];
      ui.frame = Math.max(0, s.f - 8);
      drawRally();
    }
    var box = document.getElementById("whatif-chart");
    box.innerHTML = "";
    box.appendChild(el("div", {}, ["Shot " + (w.shot + 1) + " of rally " + w.rally + ": ", player(w.hitter),
      "'s " + words(w.stroke) + ", played " + words(w.played) + " (" + words(w.outcome) + ")."]));
    var H = 44 * w.options.length + 40, W = 420, L = 6, R = 10;
    var svg = sv("svg", { viewBox: "0 0 " + W + " " + (2 * H + 30) });
    function chart(y0, title, key, lo, hi) {
      sv("text", { x: 0, y: y0 + 14, text: title, "font-weight": 600 }, svg);
      var X = function (p) { return L + (W - L - R) * p; };
      [0, 0.25, 0.5, 0.75, 1].forEach(function (p) {
        sv("line", { x1: X(p), x2: X(p), y1: y0 + 22, y2: y0 + H - 14, stroke: "#e5e5e5" }, svg);
        sv("text", { x: X(p), y: y0 + H - 2, "text-anchor": p === 0 ? "start" : p === 1 ? "end" : "middle",
                     fill: "#888", text: (100 * p) + "%" }, svg);
      });
      w.options.forEach(function (o, j) {
        var y = y0 + 22 + 44 * j;
        var played = o.option === w.played;
        sv("text", { x: L, y: y + 13, text: words(o.option) + (played ? " (played)" : "") }, svg);
        sv("text", { x: W - R, y: y + 13, "text-anchor": "end", fill: "#333",
                     text: pct(o[key], 0) + "  (95%: " + pct(o[lo], 0) + "-" + pct(o[hi], 0) + ")" }, svg);
        sv("rect", { x: X(0), y: y + 18, width: Math.max(X(o[key]) - X(0), 1), height: 16,
                     fill: COLOURS[w.hitter], "fill-opacity": 0.75 }, svg);
        sv("line", { x1: X(o[lo]), x2: X(o[hi]), y1: y + 26, y2: y + 26, stroke: "#000", "stroke-width": 2 }, svg);
        [lo, hi].forEach(function (q) {
          sv("line", { x1: X(o[q]), x2: X(o[q]), y1: y + 20, y2: y + 32, stroke: "#000", "stroke-width": 2 }, svg);
        });
      });
    }
    chart(0, "P(" + NAMES[w.hitter] + " wins the point)", "p", "lo", "hi");
    chart(H + 20, "P(" + NAMES[w.hitter] + " wins the match)", "match_p", "match_lo", "match_hi");
    box.appendChild(svg);
    var n = w.options.map(function (o) { return words(o.option) + ": " + o.n + " of " + o.n_sims; }).join(", ");
    box.appendChild(el("p", { cls: "hint", text: "Bars: estimate; whiskers: 95% Wilson interval. " +
      "Rollouts counted (realistic, decided): " + n + ". " +
      "Match probability = P(match | point lost) + P(point) x importance, with " + NAMES[w.hitter] +
      " at " + pct(w.match_if_lost, 1) + " if he loses the point and " + pct(w.match_if_won, 1) + " if he wins it." }));
  }

  // --- statistics ----------------------------------------------------------------------
  function renderStats() {
    var S = D.stats, box = document.getElementById("stats");
    var t = el("table", { cls: "stats" });
    var hasReal = NAMES.some(function (n) { return S.real2011[n]; });
    var head = [el("th", { text: "" })];
    NAMES.forEach(function (n, i) {
      head.push(el("th", {}, [player(i), " this match"]));
      if (hasReal) head.push(el("th", { cls: "real", text: "2011 slams" }));
    });
    t.appendChild(el("tr", {}, head));
    S.rows.forEach(function (row) {
      var key = row[0], unit = row[2];
      var cells = [el("td", { text: row[1] })];
      function fmt(v) {
        if (v === null || v === undefined) return "-";
        if (unit === "pct") return (100 * v).toFixed(1) + "%";
        if (unit === "kmh") return v.toFixed(0);
        return key === "points_won" ? v.toFixed(0) : v.toFixed(2);
      }
      NAMES.forEach(function (n) {
        cells.push(el("td", { text: fmt(S.match[n][key]) }));
        if (hasReal) cells.push(el("td", { cls: "real", text: S.real2011[n] ? fmt(S.real2011[n][key]) : "-" }));
      });
      t.appendChild(el("tr", {}, cells));
    });
    box.appendChild(t);
    if (hasReal) box.appendChild(el("p", { cls: "hint", text: "2011 slams: " + S.real_source + "." }));
  }

  renderHeader();
  renderTimeline();
  renderMoments();
  renderWhatifList();
  renderStats();
  renderFooter();
  window.sportsngenReport = { selectPoint: selectPoint, showWhatif: showWhatif, ui: ui };
}());
