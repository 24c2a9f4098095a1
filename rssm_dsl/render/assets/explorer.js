/* rssmc HPN explorer. Part of rssmc (MIT).
 * Reads the JSON embedded in #rssm-data (the HPN IR, the flattened net's pre/post sets, the
 * spec text, an optional playback), lays out the current page's net with dagre and draws it
 * in SVG. User text only ever reaches the page through textContent / setAttribute. */
(function () {
  "use strict";
  var SVGNS = "http://www.w3.org/2000/svg";
  var DATA = JSON.parse(document.getElementById("rssm-data").textContent);
  var IR = DATA.ir;

  // ---- indexes ---------------------------------------------------------------------------
  var pages = new Map(), places = new Map(), transitions = new Map(), fusions = new Map();
  var children = new Map(), nets = new Map();
  IR.pages.forEach(function (p) {
    pages.set(p.id, p);
    nets.set(p.id, { places: [], transitions: [], subpages: [], arcs: [] });
  });
  IR.pages.forEach(function (p) {
    if (p.parent !== null) {
      if (!children.has(p.parent)) children.set(p.parent, []);
      children.get(p.parent).push(p);
      nets.get(p.parent).subpages.push(p);
    }
  });
  IR.places.forEach(function (p) { places.set(p.id, p); nets.get(p.page).places.push(p); });
  IR.transitions.forEach(function (t) { transitions.set(t.id, t); nets.get(t.page).transitions.push(t); });
  IR.arcs.forEach(function (a) { nets.get(a.page).arcs.push(a); });
  IR.fusions.forEach(function (f) { fusions.set(f.id, f); });

  var FLAT = DATA.flat;
  var placeOf = new Map(Object.entries(FLAT.place_of));
  var flatT = new Map(Object.entries(FLAT.transitions));

  function pageOf(id) {
    if (places.has(id)) return places.get(id).page;
    if (transitions.has(id)) return transitions.get(id).page;
    if (pages.has(id)) return pages.get(id).parent;
    return null;
  }

  var descendantMemo = new Map();
  function flatPlacesUnder(pageId) {          // distinct flat places inside a page, recursively
    if (descendantMemo.has(pageId)) return descendantMemo.get(pageId);
    var s = new Set();
    nets.get(pageId).places.forEach(function (p) { s.add(placeOf.get(p.id)); });
    (children.get(pageId) || []).forEach(function (c) {
      flatPlacesUnder(c.id).forEach(function (i) { s.add(i); });
    });
    descendantMemo.set(pageId, s);
    return s;
  }

  // ---- the firing sequence ---------------------------------------------------------------
  // DATA.playback is a window of the run: window step k (0 .. fired.length) is the run's step
  // first + k, reached by firing NAMES[fired[k - 1]]. The whole marking is embedded every
  // `every` steps (checkpoints); any other step is found by firing from the checkpoint before
  // it. Steps fired by hand (the token game) follow playback step `base`.
  var PB = DATA.playback;
  var NAMES = FLAT.names;
  var FIRST = PB ? PB.first : 0;
  var EVERY = PB ? Math.max(1, PB.every) : 1;
  var base = PB ? PB.fired.length : 0;      // playback steps in use (firing by hand cuts them)
  var manual = [];                           // the steps fired by hand after step base
  var cache = null;                          // {k, marking, unsafe}: the playback step last reached
  var TIMES = PB && PB.times && PB.times.t.every(function (t) { return t !== null; }) ? PB.times : null;
  var SPAN = PB && PB.span && PB.span[0] !== null && PB.span[1] !== null ? PB.span : null;

  function fireOn(marking, tid) {            // fire on a mutable marking; returns the unsafe places
    var t = flatT.get(tid), unsafe = new Set();
    t.pre.forEach(function (p) { marking.delete(p); });
    t.post.forEach(function (p) { if (marking.has(p)) unsafe.add(p); marking.add(p); });
    return unsafe;
  }
  function played(k) {                       // playback step k (0 <= k <= base)
    if (!PB) return { transition: null, marking: new Set(FLAT.initial), unsafe: new Set(), manual: false };
    if (!cache || cache.k > k || k - cache.k > EVERY) {
      var c = k > 0 ? Math.floor((k - 1) / EVERY) : 0;  // fire at least once: the unsafe places
      cache = { k: c * EVERY, marking: new Set(PB.checkpoints[c]), unsafe: new Set() };
    }
    while (cache.k < k) {
      cache.unsafe = fireOn(cache.marking, NAMES[PB.fired[cache.k]]);
      cache.k++;
    }
    return { transition: k ? NAMES[PB.fired[k - 1]] : null, marking: cache.marking,
             unsafe: cache.unsafe, manual: false };
  }
  function stateAt(k) { return k <= base ? played(k) : manual[k - base - 1]; }
  function lastStep() { return base + manual.length; }
  function timeAt(k) {                       // the time of step k (seconds), or null
    if (!TIMES || k > base) return null;
    var lo = 0, hi = TIMES.k.length - 1;
    while (lo < hi) { var mid = (lo + hi + 1) >> 1; if (TIMES.k[mid] <= k) lo = mid; else hi = mid - 1; }
    return TIMES.t[lo];
  }
  function stepAtTime(t) {                   // the last playback step at or before time t
    var lo = -1, hi = TIMES.t.length - 1;
    while (lo < hi) { var mid = (lo + hi + 1) >> 1; if (TIMES.t[mid] <= t) lo = mid; else hi = mid - 1; }
    if (lo < 0) return 0;
    return Math.min(base, lo + 1 < TIMES.k.length ? TIMES.k[lo + 1] - 1 : base);
  }
  var step = 0, st = stateAt(0);

  function enabled(tid, marking) {
    var t = flatT.get(tid);
    if (!t) return false;                      // constant-false condition: not in the flat net
    for (var i = 0; i < t.pre.length; i++) if (!marking.has(t.pre[i])) return false;
    return true;
  }

  function fire(tid) {                          // interactive token game from the current step
    if (!enabled(tid, st.marking)) return;
    var next = new Set(st.marking), unsafe = fireOn(next, tid);
    if (step <= base) { base = step; manual = []; } else { manual = manual.slice(0, step - base); }
    manual.push({ transition: tid, marking: next, unsafe: unsafe, manual: true });
    setStep(step + 1);
  }

  // ---- small DOM helpers -----------------------------------------------------------------
  function $(id) { return document.getElementById(id); }
  function svg(tag, attrs, parent) {
    var e = document.createElementNS(SVGNS, tag);
    Object.keys(attrs || {}).forEach(function (k) { e.setAttribute(k, String(attrs[k])); });
    if (parent) parent.appendChild(e);
    return e;
  }
  function html(tag, text, parent, cls) {
    var e = document.createElement(tag);
    if (text !== undefined && text !== null) e.textContent = String(text);
    if (cls) e.className = cls;
    if (parent) parent.appendChild(e);
    return e;
  }
  function linkButton(text, onclick, parent) {
    var b = html("button", text, parent, "link");
    b.type = "button";
    b.addEventListener("click", onclick);
    return b;
  }
  function clear(e) { while (e.firstChild) e.removeChild(e.firstChild); }
  function clip(s, n) { return s.length > n ? s.slice(0, n - 1) + "\u2026" : s; }
  function where(span) { return span.file + ":" + span.line; }

  // text measurement for node sizes
  var measureSvg = svg("svg", { width: 0, height: 0, style: "position:absolute;visibility:hidden" });
  document.body.appendChild(measureSvg);
  var measureText = svg("text", { "font-size": 11 }, measureSvg);
  var widths = new Map();
  function textWidth(s, size) {
    var key = size + "|" + s;
    if (!widths.has(key)) {
      measureText.setAttribute("font-size", String(size));
      measureText.textContent = s;
      widths.set(key, measureText.getComputedTextLength());
    }
    return widths.get(key);
  }

  // ---- layout (dagre), cached per page ---------------------------------------------------
  var SHAPE = { place: [28, 28], transition: [12, 34], page: [42, 42] };
  var LINE = 13;
  function labelsOf(kind, obj) {
    if (kind === "place") {
      var l = [[obj.id, "name", 11]];
      if (obj.operation) l.push([clip(obj.operation.text, 40), "sub", 10]);
      return l;
    }
    if (kind === "transition") {
      var lt = [[obj.id, "name", 11]];
      if (obj.condition) lt.push(["[" + clip(obj.condition.text, 40) + "]", "cond", 10]);
      return lt;
    }
    return [[obj.id, "name", 11], [clip(obj.label, 40), "sub", 10]];
  }

  var layouts = new Map();
  function layout(pageId) {
    if (layouts.has(pageId)) return layouts.get(pageId);
    var net = nets.get(pageId);
    var g = new dagre.graphlib.Graph({ multigraph: true });
    g.setGraph({ rankdir: "LR", nodesep: 22, ranksep: 34, edgesep: 10, marginx: 20, marginy: 20 });
    g.setDefaultEdgeLabel(function () { return {}; });
    var nodes = [];
    function add(kind, obj) {
      var labels = labelsOf(kind, obj), sh = SHAPE[kind];
      var w = sh[0];
      labels.forEach(function (l) { w = Math.max(w, textWidth(l[0], l[2])); });
      var h = sh[1] + 2 * (labels.length * LINE + 4);
      g.setNode(obj.id, { width: w + 8, height: h });
      nodes.push({ id: obj.id, kind: kind, obj: obj, labels: labels });
    }
    net.places.forEach(function (p) { add("place", p); });
    net.transitions.forEach(function (t) { add("transition", t); });
    net.subpages.forEach(function (p) { add("page", p); });
    net.arcs.forEach(function (a, i) { g.setEdge(a.source, a.target, {}, "arc" + i); });
    dagre.layout(g);
    nodes.forEach(function (n) { var d = g.node(n.id); n.x = d.x; n.y = d.y; n.w = d.width; n.h = d.height; });
    var byId = new Map(nodes.map(function (n) { return [n.id, n]; }));
    var arcs = net.arcs.map(function (a, i) {
      var pts = g.edge({ v: a.source, w: a.target, name: "arc" + i }).points || [];
      return { source: a.source, target: a.target,
               points: route(byId.get(a.source), byId.get(a.target), pts) };
    });
    var gr = g.graph();
    var out = { nodes: nodes, arcs: arcs, width: gr.width || 100, height: gr.height || 100 };
    layouts.set(pageId, out);
    return out;
  }

  function boundary(n, toward) {              // where a line from the shape's centre leaves it
    var dx = toward.x - n.x, dy = toward.y - n.y, len = Math.hypot(dx, dy) || 1;
    if (n.kind === "transition") {
      var hw = SHAPE.transition[0] / 2, hh = SHAPE.transition[1] / 2;
      var s = Math.min(dx ? hw / Math.abs(dx) : Infinity, dy ? hh / Math.abs(dy) : Infinity);
      return { x: n.x + dx * s, y: n.y + dy * s };
    }
    var r = SHAPE[n.kind][0] / 2;
    return { x: n.x + dx / len * r, y: n.y + dy / len * r };
  }
  function inside(n, p) { return Math.abs(p.x - n.x) < n.w / 2 && Math.abs(p.y - n.y) < n.h / 2; }
  function route(src, dst, pts) {
    var inner = pts.slice(1, -1).filter(function (p) { return !inside(src, p) && !inside(dst, p); });
    var first = boundary(src, inner.length ? inner[0] : dst);
    var last = boundary(dst, inner.length ? inner[inner.length - 1] : src);
    return [first].concat(inner, [last]);
  }

  // ---- drawing ---------------------------------------------------------------------------
  var canvas = $("canvas"), viewport = null, view = { x: 0, y: 0, k: 1 }, current = IR.root;
  var selected = null, hits = new Set();

  function applyView() {
    if (viewport) viewport.setAttribute("transform", "translate(" + view.x + "," + view.y + ") scale(" + view.k + ")");
  }
  function fit() {
    var L = layout(current), r = canvas.getBoundingClientRect();
    var k = Math.min(r.width / L.width, r.height / L.height, 1.6);
    if (!isFinite(k) || k <= 0) k = 1;
    view = { k: k, x: (r.width - L.width * k) / 2, y: (r.height - L.height * k) / 2 };
    applyView();
  }

  function draw() {
    var L = layout(current), m = st.marking;
    clear(canvas);
    var defs = svg("defs", {}, canvas);
    var marker = svg("marker", { id: "arrowhead", viewBox: "0 0 10 10", refX: 10, refY: 5,
                                 markerWidth: 7, markerHeight: 7, orient: "auto-start-reverse" }, defs);
    svg("path", { d: "M0,0 L10,5 L0,10 z" }, marker);
    viewport = svg("g", { id: "viewport" }, canvas);
    applyView();
    var arcs = svg("g", { "class": "arcs" }, viewport);
    L.arcs.forEach(function (a) {
      var d = a.points.map(function (p, i) { return (i ? "L" : "M") + p.x.toFixed(1) + "," + p.y.toFixed(1); }).join(" ");
      svg("path", { "class": "arc", d: d, "marker-end": "url(#arrowhead)",
                    "data-source": a.source, "data-target": a.target }, arcs);
    });
    var layer = svg("g", { "class": "nodes" }, viewport);
    L.nodes.forEach(function (n) {
      var cls = ["node", n.kind];
      if (n.kind === "place") {
        if (n.obj.fusion) cls.push("fused");
        if (m.has(placeOf.get(n.id))) cls.push("marked");
        if (st.unsafe.has(placeOf.get(n.id))) cls.push("unsafe");
      } else if (n.kind === "transition") {
        if (enabled(n.id, m)) cls.push("enabled");
        if (st.transition === n.id) cls.push("fired");
      }
      if (selected === n.id) cls.push("selected");
      if (hits.has(n.id)) cls.push("hit");
      var g = svg("g", { "class": cls.join(" "), "data-id": n.id, "data-kind": n.kind,
                         transform: "translate(" + n.x.toFixed(1) + "," + n.y.toFixed(1) + ")" }, layer);
      svg("title", {}, g).textContent = tooltip(n.kind, n.obj);
      var sh = SHAPE[n.kind];
      if (n.kind === "place") {
        svg("circle", { "class": "shape", r: sh[0] / 2 }, g);
        if (m.has(placeOf.get(n.id))) svg("circle", { "class": "token", r: 5 }, g);
      } else if (n.kind === "transition") {
        svg("rect", { "class": "shape", x: -sh[0] / 2, y: -sh[1] / 2, width: sh[0], height: sh[1] }, g);
      } else {
        svg("circle", { "class": "shape", r: sh[0] / 2 }, g);
        svg("circle", { "class": "ring", r: sh[0] / 2 - 4 }, g);
        var tokens = 0;
        flatPlacesUnder(n.id).forEach(function (i) { if (m.has(i)) tokens++; });
        if (tokens) {
          g.setAttribute("data-tokens", String(tokens));
          svg("circle", { "class": "inner", r: 8 }, g);
          var c = svg("text", { "class": "count", "text-anchor": "middle", y: 3 }, g);
          c.textContent = String(tokens);
        }
      }
      var y = sh[1] / 2 + 4;
      n.labels.forEach(function (l) {
        y += LINE;
        var t = svg("text", { "class": l[1], "text-anchor": "middle", y: y - 3 }, g);
        t.textContent = l[0];
      });
      g.addEventListener("click", function (ev) { ev.stopPropagation(); clicked(n); });
      g.addEventListener("dblclick", function (ev) {
        ev.stopPropagation();
        if (n.kind === "transition" && enabled(n.id, st.marking)) fire(n.id);
      });
    });
  }

  function tooltip(kind, o) {
    var lines = [o.id + (o.label && o.label !== o.id ? ": " + o.label : "")];
    if (kind === "place" && o.operation) lines.push("operation: " + o.operation.text);
    if (kind === "place" && o.fusion) lines.push("fused: " + o.fusion);
    if (kind === "transition" && o.condition) lines.push("condition: [" + o.condition.text + "]");
    if (kind === "page") lines.push("click to open");
    lines.push(where(o.span));
    return lines.join("\n");
  }

  function clicked(n) {
    if (n.kind === "page") { go(n.id, null); return; }
    select(n.id);
  }

  // ---- navigation ------------------------------------------------------------------------
  var fitted = null;
  function go(pageId, sel, replace) {
    if (!pages.has(pageId)) return;
    current = pageId;
    selected = sel;
    draw();
    if (fitted !== current) { fit(); fitted = current; }
    crumbs(); headline(); treeMark(); details();
    var h = "#page=" + encodeURIComponent(pageId) + (sel ? "&sel=" + encodeURIComponent(sel) : "");
    if (location.hash !== h) {
      if (replace) history.replaceState(null, "", h); else history.pushState(null, "", h);
    }
  }
  function select(id) {
    selected = id;
    draw(); details();
    var h = "#page=" + encodeURIComponent(current) + "&sel=" + encodeURIComponent(id);
    if (location.hash !== h) history.replaceState(null, "", h);
  }
  function fromHash() {
    var q = new URLSearchParams(location.hash.slice(1));
    var p = q.get("page");
    go(p && pages.has(p) ? p : IR.root, q.get("sel"), true);
  }
  window.addEventListener("popstate", fromHash);

  function ancestry(pageId) {
    var chain = [];
    for (var p = pages.get(pageId); p; p = p.parent !== null ? pages.get(p.parent) : null) chain.unshift(p);
    return chain;
  }
  function crumbs() {
    var c = $("crumbs");
    clear(c);
    ancestry(current).forEach(function (p, i, all) {
      if (i) html("span", "\u203a", c, "sep");
      var b = linkButton(p.id, function () { go(p.id, null); }, c);
      b.setAttribute("data-page", p.id);
      if (i === all.length - 1) b.disabled = true;
    });
    $("up").disabled = pages.get(current).parent === null;
  }
  function headline() {
    var p = pages.get(current), h = $("pagehead");
    clear(h);
    html("span", p.id, h, "title");
    html("span", "  " + p.label + " \u2014 " + p.kind + ", layer " + p.layer +
         (p.sublayer ? "." + p.sublayer : "") + " \u2014 ", h, "sub");
    specLink(p.span, h);
    if (DATA.figures[p.id]) {
      html("span", " \u2014 ", h, "sub");
      var a = html("a", "SVG figure", h);
      a.href = DATA.figures[p.id];
    }
  }

  // hierarchy tree
  var treeItems = new Map();
  function buildTree() {
    function item(p, ul) {
      var li = html("li", null, ul);
      var b = linkButton(p.id, function () { go(p.id, null); }, li);
      b.title = p.label;
      b.setAttribute("data-page", p.id);
      treeItems.set(p.id, li);
      var kids = children.get(p.id) || [];
      if (kids.length) {
        var sub = html("ul", null, li);
        kids.forEach(function (k) { item(k, sub); });
      }
    }
    item(pages.get(IR.root), $("pagetree"));
    IR.devices.forEach(function (d) { item(pages.get(d), $("devicetree")); });
    if (!IR.devices.length) html("li", "none", $("devicetree"));
  }
  function treeMark() {
    treeItems.forEach(function (li, id) { li.classList.toggle("current", id === current); });
    var li = treeItems.get(current);
    if (li && li.scrollIntoView) li.scrollIntoView({ block: "nearest" });
  }

  // ---- details and source ----------------------------------------------------------------
  function specLink(span, parent) {
    var b = linkButton(where(span), function () { showSource(span.file, span.line); }, parent);
    b.className = "link code speclink";
    return b;
  }
  function lineText(file, n) {
    var lines = DATA.sources[file];
    return lines && n >= 1 && n <= lines.length ? lines[n - 1] : null;
  }
  function details() {
    var d = $("details");
    clear(d);
    if (!selected || !(places.has(selected) || transitions.has(selected) || pages.has(selected))) {
      html("p", "Click a place or a transition to see it; click a page (double circle) to open it; " +
           "double-click an enabled (green) transition to fire it.", d);
      return;
    }
    var kind = places.has(selected) ? "place" : transitions.has(selected) ? "transition" : "page";
    var o = kind === "place" ? places.get(selected) : kind === "transition" ? transitions.get(selected) : pages.get(selected);
    var dl = html("dl", null, d);
    dl.setAttribute("data-id", o.id);
    function row(k, v) { html("dt", k, dl); var dd = html("dd", null, dl); if (v !== undefined) dd.textContent = v; return dd; }
    row(kind, o.id).className = "code";
    if (o.label) row("label", o.label);
    var inPage = row("page");
    var pid = kind === "page" ? o.parent : o.page;
    if (pid !== null) linkButton(pid, function () { go(pid, null); }, inPage);
    if (kind === "place") {
      var m = st.marking.has(placeOf.get(o.id));
      row("marked", m ? "yes (one token)" : "no").setAttribute("data-marked", String(m));
      if (o.operation) {
        row("operation", o.operation.kind + (o.operation.void ? " (void)" : ""));
        row("does", o.operation.text).className = "code op";
        if (o.operation.channel) row("channel", o.operation.channel);
      } else {
        row("operation", "none");
      }
      if (o.fusion) {
        var f = fusions.get(o.fusion), dd = row("fused");
        html("div", f.id, dd, "code");
        html("div", f.label, dd);
        f.places.forEach(function (q) {
          if (q === o.id) return;
          var div = html("div", null, dd);
          linkButton(q, function () { go(places.get(q).page, q); }, div);
        });
      }
    } else if (kind === "transition") {
      row("role", o.role);
      if (o.condition) {
        row("condition", "[" + o.condition.text + "]").className = "code cond";
        var kinds = o.condition.kind + (o.condition.constant === null ? "" : ", always " + o.condition.constant);
        row("kind", kinds);
      } else {
        row("condition", "none (true)");
      }
      var en = enabled(o.id, st.marking);
      var dd2 = row("enabled", flatT.has(o.id) ? (en ? "yes" : "no") : "never (condition constant false)");
      if (en) {
        var fb = html("button", "Fire", dd2);
        fb.type = "button"; fb.id = "fire";
        fb.addEventListener("click", function () { fire(o.id); });
      }
    }
    var spec = row("spec");
    specLink(o.span, spec);
    var text = lineText(o.span.file, o.span.line);
    if (text !== null) html("span", text, spec, "specline");
  }
  function showSource(file, line) {
    var box = $("source"), lines = DATA.sources[file];
    box.hidden = false;
    $("srcname").textContent = file;
    var body = $("srclines");
    clear(body);
    if (!lines) { html("div", "(the text of this file is not embedded)", body); return; }
    var hit = null;
    lines.forEach(function (t, i) {
      var div = html("div", null, body);
      html("span", String(i + 1), div, "ln");
      div.appendChild(document.createTextNode(t));
      if (i + 1 === line) { div.className = "hit"; hit = div; }
    });
    if (hit) body.scrollTop = Math.max(0, hit.offsetTop - body.offsetTop - body.clientHeight / 3);
  }

  // ---- search ----------------------------------------------------------------------------
  var index = [];
  IR.pages.forEach(function (p) { index.push({ id: p.id, kind: "page", label: p.label }); });
  IR.places.forEach(function (p) { index.push({ id: p.id, kind: "place", label: (p.label || "") + (p.operation ? " " + p.operation.text : "") }); });
  IR.transitions.forEach(function (t) { index.push({ id: t.id, kind: "transition", label: (t.label || "") + (t.condition ? " [" + t.condition.text + "]" : "") }); });
  function search(q) {
    var ul = $("results");
    clear(ul);
    hits = new Set();
    q = q.trim().toLowerCase();
    if (!q) { draw(); return; }
    var found = index.filter(function (e) { return e.id.toLowerCase().indexOf(q) >= 0 || e.label.toLowerCase().indexOf(q) >= 0; });
    found.slice(0, 200).forEach(function (e) {
      var li = html("li", null, ul);
      li.setAttribute("data-id", e.id);
      linkButton(e.id, function () {
        if (e.kind === "page") go(e.id, null); else go(pageOf(e.id), e.id);
        clear(ul);
      }, li);
      html("span", e.kind + (e.label ? " \u2014 " + clip(e.label, 60) : ""), li, "kind");
      hits.add(e.id);
    });
    if (found.length > 200) html("li", (found.length - 200) + " more\u2026", ul);
    if (!found.length) html("li", "no match", ul);
    draw();
  }
  $("search").addEventListener("input", function (ev) { search(ev.target.value); });
  $("search").addEventListener("keydown", function (ev) {
    if (ev.key === "Escape") { ev.target.value = ""; search(""); }
  });

  // ---- playback ----------------------------------------------------------------------------
  function setStep(k) {
    step = Math.max(0, Math.min(k, lastStep()));
    st = stateAt(step);
    cursor();
    if (st.transition && $("follow").checked) {
      var p = pageOf(st.transition);
      if (p !== current) { go(p, null); playInfo(); return; }
    }
    draw(); details(); playInfo();
  }
  function seconds(t) { return String(+t.toPrecision(6)) + " s"; }
  function playInfo() {
    var slider = $("stepslider"), info = $("stepinfo"), box = $("stepbox");
    slider.max = String(lastStep());
    slider.value = String(step);
    box.min = String(FIRST);
    box.max = String(FIRST + lastStep());
    if (document.activeElement !== box) box.value = String(FIRST + step);
    clear(info);
    info.setAttribute("data-step", String(FIRST + step));
    info.setAttribute("data-marking", Array.from(st.marking).sort(function (a, b) { return a - b; }).join(" "));
    var t = timeAt(step);
    if (t === null) info.removeAttribute("data-time"); else info.setAttribute("data-time", String(t));
    if (TIMES && document.activeElement !== $("timebox")) $("timebox").value = t === null ? "" : String(t);
    var src = PB ? PB.kind + " " + PB.source : "token game";
    html("span", "step " + (FIRST + step) + " / " + (FIRST + lastStep()) + " (" + src + ")", info);
    if (t !== null) html("span", " \u2014 t = " + seconds(t), info, "time");
    if (st.transition) {
      html("span", " \u2014 fired ", info);
      var tid = st.transition;
      var b = linkButton(tid, function () { go(pageOf(tid), tid); }, info);
      b.id = "firedlink";
      if (st.manual) html("span", " (by you)", info);
      if (st.unsafe.size) html("span", " \u2014 UNSAFE: a place got a second token", info);
    } else {
      html("span", step === 0 && FIRST === 0 ? " \u2014 initial marking" : " \u2014 first step of the window", info);
    }
    var finished = FLAT.final.length && FLAT.final.every(function (q) { return st.marking.has(q); });
    var any = false;
    flatT.forEach(function (tr, id) { if (!any && enabled(id, st.marking)) any = true; });
    if (finished) html("span", " \u2014 the system has finished", info, "end");
    else if (!any) html("span", " \u2014 nothing can fire: deadlock", info, "end");
    $("first").disabled = $("prev").disabled = step === 0;
    $("last").disabled = $("next").disabled = step === lastStep();
  }
  function windowNote(extra) {                 // which steps of the run this file holds
    var w = $("window");
    clear(w);
    var text = [];
    if (PB && !PB.whole) {
      var span = TIMES ? " (t = " + seconds(timeAt(0)) + " to " + seconds(timeAt(PB.fired.length)) + ")" : "";
      text.push("This file holds steps " + PB.first + " to " + (PB.first + PB.fired.length) + span +
                " of the " + PB.total + " firings of the " + PB.kind +
                (SPAN ? " (t = " + seconds(SPAN[0]) + " to " + seconds(SPAN[1]) + ")" : "") +
                ". To see others, render it again: " + PB.hint + ".");
    }
    if (extra) text.push(extra);
    w.hidden = !text.length;
    text.forEach(function (t) { html("div", t, w); });
  }
  function seekRun(n) {                        // go to the run's step n
    if (isNaN(n)) return;
    var k = n - FIRST;
    windowNote(k < 0 || k > lastStep() ? "Step " + n + " is not in this file (steps " + FIRST + " to " +
               (FIRST + lastStep()) + ")." : null);
    setStep(k);
  }
  function seekTime(t) {                       // go to the last step at or before time t
    if (!TIMES || isNaN(t)) return;
    var outside = t < timeAt(0) || t > timeAt(base);
    windowNote(outside ? "t = " + seconds(t) + " is not in this file (t = " + seconds(timeAt(0)) + " to " +
               seconds(timeAt(base)) + ")." : null);
    setStep(stepAtTime(t));
  }
  $("first").addEventListener("click", function () { setStep(0); });
  $("prev").addEventListener("click", function () { setStep(step - 1); });
  $("next").addEventListener("click", function () { setStep(step + 1); });
  $("last").addEventListener("click", function () { setStep(lastStep()); });
  $("stepslider").addEventListener("input", function (ev) { setStep(parseInt(ev.target.value, 10)); });
  $("stepbox").addEventListener("change", function (ev) { seekRun(parseInt(ev.target.value, 10)); });
  $("timebox").addEventListener("change", function (ev) { seekTime(parseFloat(ev.target.value)); });
  $("up").addEventListener("click", function () {
    var p = pages.get(current);
    if (p.parent !== null) go(p.parent, null);
  });
  document.addEventListener("keydown", function (ev) {
    if (ev.target && ev.target.tagName === "INPUT" && ev.target.type !== "range") return;
    if (ev.key === "ArrowRight") setStep(step + 1);
    else if (ev.key === "ArrowLeft") setStep(step - 1);
  });

  // ---- the series of the run -------------------------------------------------------------
  // DATA.series: charts (the rows of `rssmc plot`), each with lines of (t, v) samples already
  // decimated in Python (v null: a gap); drawn as steps in plain SVG. A vertical cursor marks
  // the time of the current playback step; a click on a chart goes to the step at that time.
  var SER = DATA.series;
  var COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf", "#8c564b",
                "#e377c2", "#7f7f7f", "#bcbd22"];
  var charts = [], T0 = 0, T1 = 1;

  function timeRange() {
    var lo = Infinity, hi = -Infinity;
    SER.charts.forEach(function (c) {
      c.lines.forEach(function (l) {
        if (l.t.length) { lo = Math.min(lo, l.t[0]); hi = Math.max(hi, l.t[l.t.length - 1]); }
      });
    });
    if (SPAN) { lo = Math.min(lo, SPAN[0]); hi = Math.max(hi, SPAN[1]); }
    if (!isFinite(lo)) { lo = 0; hi = 1; }
    if (hi <= lo) hi = lo + 1;
    T0 = lo; T1 = hi;
  }
  function ticks(lo, hi, n) {                  // about n round numbers between lo and hi
    var raw = (hi - lo) / Math.max(n, 1), mag = Math.pow(10, Math.floor(Math.log10(raw)));
    var unit = [1, 2, 5, 10].map(function (f) { return f * mag; }).find(function (u) { return u >= raw; });
    var out = [];
    for (var v = Math.ceil(lo / unit) * unit; v <= hi + unit * 1e-9; v += unit) out.push(+v.toPrecision(12));
    return out;
  }
  function number(v) {
    var a = Math.abs(v);
    return a !== 0 && (a >= 1e5 || a < 1e-3) ? v.toExponential(2) : String(+v.toPrecision(4));
  }
  function valueAt(l, t) {                     // the value of a line drawn as steps at time t
    var lo = -1, hi = l.t.length - 1;
    while (lo < hi) { var mid = (lo + hi + 1) >> 1; if (l.t[mid] <= t) lo = mid; else hi = mid - 1; }
    return lo < 0 ? null : l.v[lo];
  }
  function yDomain(c) {
    if (c.kind === "category") return [-0.5, Math.max(c.labels.length, 1) - 0.5];
    var lo = Infinity, hi = -Infinity;
    c.lines.forEach(function (l) {
      l.v.forEach(function (v) { if (v !== null) { if (v < lo) lo = v; if (v > hi) hi = v; } });
    });
    if (!isFinite(lo)) return [0, 1];
    if (hi === lo) { var d = Math.abs(lo) * 0.1 || 1; return [lo - d, hi + d]; }
    var pad = (hi - lo) * 0.05;
    return [lo - pad, hi + pad];
  }
  function stepPath(l, x, y) {                 // the samples as steps (held until the next one)
    var d = [], pen = false, lastY = 0;
    for (var i = 0; i < l.t.length; i++) {
      if (l.v[i] === null) { pen = false; continue; }
      var px = x(l.t[i]).toFixed(1), py = y(l.v[i]).toFixed(1);
      if (!pen) d.push("M" + px + "," + py);
      else d.push("H" + px + (py !== lastY ? "V" + py : ""));
      pen = true; lastY = py;
    }
    return d.join("");
  }
  function lineLabel(c, l) { return l.name.length > c.title.length ? l.name.slice(c.title.length) : l.name; }

  function drawChart(c, box, width, bottomAxis) {
    var div = html("div", null, box, "chart");
    div.setAttribute("data-title", c.title);
    var head = html("div", null, div, "head");
    html("span", c.title, head, "title");
    if (c.lines.length > 1) {
      c.lines.forEach(function (l, j) {
        var key = html("span", "\u25a0 " + lineLabel(c, l), head, "key");
        key.style.color = COLORS[j % COLORS.length];
      });
    }
    var readout = html("span", "", head, "readout");
    var cat = c.kind === "category";
    var left = 58;
    if (cat) c.labels.forEach(function (lb) { left = Math.max(left, Math.min(180, textWidth(lb, 10) + 12)); });
    var top = 6, ph = cat ? Math.max(36, 16 * c.labels.length) : 80, bottom = bottomAxis ? 20 : 6;
    var pw = Math.max(50, width - left - 12), H = top + ph + bottom;
    var dom = yDomain(c);
    function x(t) { return left + (t - T0) / (T1 - T0) * pw; }
    function y(v) { return top + (dom[1] - v) / (dom[1] - dom[0]) * ph; }
    var s = svg("svg", { width: width, height: H, viewBox: "0 0 " + width + " " + H,
                         "data-t0": T0, "data-t1": T1, "data-y0": dom[0], "data-y1": dom[1],
                         "data-left": left, "data-top": top, "data-width": pw, "data-height": ph }, div);
    svg("rect", { "class": "frame", x: left, y: top, width: pw, height: ph }, s);
    if (TIMES && PB && !PB.whole) {            // the steps this file holds
      var a = x(timeAt(0)), b = x(timeAt(PB.fired.length));
      svg("rect", { "class": "window", x: a, y: top, width: Math.max(1, b - a), height: ph }, s);
    }
    ticks(T0, T1, Math.max(2, Math.floor(pw / 90))).forEach(function (t) {
      svg("line", { "class": "grid", x1: x(t), x2: x(t), y1: top, y2: top + ph }, s);
      if (bottomAxis) {
        svg("text", { "class": "tick", x: x(t), y: top + ph + 14, "text-anchor": "middle" }, s).textContent = number(t) + " s";
      }
    });
    var levels = cat ? c.labels.map(function (lb, i) { return [i, lb]; })
                     : ticks(dom[0], dom[1], Math.max(2, Math.floor(ph / 28))).map(function (v) { return [v, number(v)]; });
    levels.forEach(function (lv) {
      svg("line", { "class": "grid", x1: left, x2: left + pw, y1: y(lv[0]), y2: y(lv[0]) }, s);
      svg("text", { "class": "tick", x: left - 4, y: y(lv[0]) + 3, "text-anchor": "end" }, s).textContent = lv[1];
    });
    c.lines.forEach(function (l, j) {
      var path = svg("path", { "class": "series", d: stepPath(l, x, y), stroke: COLORS[j % COLORS.length],
                               "data-name": l.name, "data-points": l.t.length, "data-samples": l.samples }, s);
      svg("title", {}, path).textContent = l.name + " (" + l.samples + " samples" +
        (l.decimated ? "; " + l.t.length + " drawn: the smallest and largest of each stretch" : "") + ")";
    });
    if (!c.lines.some(function (l) { return l.t.length; })) {
      svg("text", { "class": "empty", x: left + 8, y: top + ph / 2 }, s).textContent = "(no samples)";
    }
    var cur = svg("line", { "class": "cursor", x1: left, x2: left, y1: top, y2: top + ph, visibility: "hidden" }, s);
    function timeOf(ev) {
      var r = s.getBoundingClientRect();
      var px = (ev.clientX - r.left) * width / r.width;
      return T0 + (px - left) / pw * (T1 - T0);
    }
    s.addEventListener("mousemove", function (ev) {
      var t = timeOf(ev);
      readout.textContent = "t = " + number(t) + " s: " + c.lines.map(function (l) {
        var v = valueAt(l, t);
        var shown = v === null ? "\u2014" : cat ? (c.labels[v] !== undefined ? c.labels[v] : String(v)) : number(v);
        return (c.lines.length > 1 ? lineLabel(c, l) + " " : "") + shown;
      }).join(", ");
    });
    s.addEventListener("mouseleave", function () { readout.textContent = ""; });
    s.addEventListener("click", function (ev) { if (TIMES) seekTime(timeOf(ev)); });
    return { cursor: cur, x: x };
  }
  function drawCharts() {
    if (!SER) return;
    var box = $("charts");
    clear(box);
    charts = [];
    var width = Math.max(320, box.clientWidth - 4);
    SER.charts.forEach(function (c, i) { charts.push(drawChart(c, box, width, i === SER.charts.length - 1)); });
    cursor();
  }
  function cursor() {                          // the time of the current step on every chart
    var t = timeAt(step);
    charts.forEach(function (ch) {
      if (t === null) { ch.cursor.setAttribute("visibility", "hidden"); ch.cursor.removeAttribute("data-time"); return; }
      var px = ch.x(t).toFixed(1);
      ch.cursor.setAttribute("x1", px); ch.cursor.setAttribute("x2", px);
      ch.cursor.setAttribute("visibility", "visible");
      ch.cursor.setAttribute("data-time", String(t));
    });
  }
  function seriesPanel() {
    if (!SER) return;
    $("series").hidden = false;
    timeRange();
    var head = $("serieshead"), decimated = 0;
    SER.charts.forEach(function (c) { c.lines.forEach(function (l) { if (l.decimated) decimated++; }); });
    html("span", "Series of " + SER.source + " (system " + SER.system + "): " + SER.series + " series" +
         (SER.in_file > SER.series ? " of the " + SER.in_file + " in the file" : "") +
         (decimated ? "; " + decimated + " drawn from fewer points than recorded (the smallest and largest of each stretch kept)" : "") +
         (TIMES ? "; click a chart to go to the step at that time" : ""), head);
    drawCharts();
    var pending = false;
    window.addEventListener("resize", function () {
      if (pending) return;
      pending = true;
      requestAnimationFrame(function () { pending = false; drawCharts(); });
    });
  }

  // ---- pan and zoom ----------------------------------------------------------------------
  function zoom(f, cx, cy) {
    view.x = cx - (cx - view.x) * f; view.y = cy - (cy - view.y) * f; view.k *= f; applyView();
  }
  canvas.addEventListener("wheel", function (ev) {
    ev.preventDefault();
    var r = canvas.getBoundingClientRect();
    zoom(ev.deltaY < 0 ? 1.15 : 1 / 1.15, ev.clientX - r.left, ev.clientY - r.top);
  }, { passive: false });
  var drag = null;
  canvas.addEventListener("mousedown", function (ev) { drag = { x: ev.clientX, y: ev.clientY }; canvas.classList.add("dragging"); });
  window.addEventListener("mousemove", function (ev) {
    if (!drag) return;
    view.x += ev.clientX - drag.x; view.y += ev.clientY - drag.y;
    drag = { x: ev.clientX, y: ev.clientY }; applyView();
  });
  window.addEventListener("mouseup", function () { drag = null; canvas.classList.remove("dragging"); });
  $("fit").addEventListener("click", fit);
  $("zin").addEventListener("click", function () { var r = canvas.getBoundingClientRect(); zoom(1.25, r.width / 2, r.height / 2); });
  $("zout").addEventListener("click", function () { var r = canvas.getBoundingClientRect(); zoom(0.8, r.width / 2, r.height / 2); });
  window.addEventListener("resize", fit);

  // ---- start -----------------------------------------------------------------------------
  $("sysname").textContent = IR.system;
  $("timelabel").hidden = !TIMES;
  buildTree();
  seriesPanel();
  fromHash();
  playInfo();
  windowNote(null);
  document.body.setAttribute("data-ready-ms", String(performance.now()));
  document.body.setAttribute("data-ready", "true");
})();
